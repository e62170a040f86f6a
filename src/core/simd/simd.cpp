#include "simd/simd.h"

#include <atomic>
#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <mutex>

namespace ground_filter {
namespace simd {

namespace {

constexpr const char* kNames[] = {"portable", "sse", "neon", "avx2", "avx512"};

bool cpuRuns(Level level) {
  switch (level) {
    case Level::kPortable:
      return true;
#if defined(__x86_64__) && defined(__GNUC__)
    case Level::kSse:
      return true;  // SSE2 is part of x86-64
    case Level::kAvx2:
      return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("popcnt");
    case Level::kAvx512:
      return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx2");
#elif defined(__aarch64__)
    case Level::kNeon:
      return true;  // Advanced SIMD is part of AArch64
#endif
    default:
      return false;
  }
}

Level highest() {
  for (int l = static_cast<int>(Level::kAvx512); l > 0; --l) {
    if (cpuRuns(static_cast<Level>(l))) return static_cast<Level>(l);
  }
  return Level::kPortable;
}

// The environment's choice, resolved once; -1 until then.
std::atomic<int> g_active{-1};
std::once_flag g_env_once;
std::string g_env_note;  // ", GF_SIMD=<value>" when the variable was set

void readEnvironment() {
  const char* env = std::getenv("GF_SIMD");
  if (env != nullptr && *env != '\0') g_env_note = std::string(", GF_SIMD=") + env;
  std::string message;
  const Level level = resolveLevel(env, &message);
  if (!message.empty()) std::fprintf(stderr, "[ground_filter] %s\n", message.c_str());
  int unset = -1;
  g_active.compare_exchange_strong(unset, static_cast<int>(level));
}

}  // namespace

const char* levelName(Level level) {
  const int i = static_cast<int>(level);
  return i >= 0 && i <= static_cast<int>(Level::kAvx512) ? kNames[i] : "unknown";
}

bool parseLevel(const std::string& text, Level* level) {
  std::string lower;
  for (char c : text) lower += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  for (int i = 0; i <= static_cast<int>(Level::kAvx512); ++i) {
    if (lower == kNames[i]) {
      *level = static_cast<Level>(i);
      return true;
    }
  }
  return false;
}

bool supported(Level level) { return cpuRuns(level); }

Level resolveLevel(const char* value, std::string* message) {
  const Level fallback = highest();
  std::string why;
  Level asked = fallback;
  if (value != nullptr && *value != '\0') {
    if (!parseLevel(value, &asked)) {
      why = std::string("GF_SIMD=") + value +
            " is not a SIMD level (portable, sse, neon, avx2, avx512): using " +
            levelName(fallback);
      asked = fallback;
    } else if (!cpuRuns(asked)) {
      why = std::string("GF_SIMD=") + value + ": this CPU or build cannot run it: using " +
            levelName(fallback);
      asked = fallback;
    }
  }
  if (message != nullptr) *message = why;
  return asked;
}

Level best() {
  static const Level b = highest();
  return b;
}

Level active() {
  int v = g_active.load(std::memory_order_relaxed);
  if (v < 0) {
    std::call_once(g_env_once, readEnvironment);
    v = g_active.load(std::memory_order_relaxed);
  }
  return static_cast<Level>(v);
}

std::string cpuModel() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  // x86: "model name"; aarch64 kernels: "Model" on some boards, else the implementer / part ids.
  std::string part;
  while (std::getline(in, line)) {
    const auto colon = line.find(':');
    if (colon == std::string::npos) continue;
    std::string key = line.substr(0, colon);
    while (!key.empty() && std::isspace(static_cast<unsigned char>(key.back()))) key.pop_back();
    std::string value = line.substr(colon + 1);
    while (!value.empty() && std::isspace(static_cast<unsigned char>(value.front()))) {
      value.erase(value.begin());
    }
    if (key == "model name" || key == "Model") return value;
    if (key == "CPU part" && part.empty()) part = "CPU part " + value;
  }
  return part.empty() ? "unknown" : part;
}

std::string describe() {
  const Level a = active();  // reads GF_SIMD first, so the note below is set
  return "CPU " + cpuModel() + "; SIMD " + levelName(a) + " (best " + levelName(best()) +
         g_env_note + ")";
}

bool setActive(Level level) {
  if (!cpuRuns(level)) return false;
  active();  // the environment is read once, before any override, never after it
  g_active.store(static_cast<int>(level), std::memory_order_relaxed);
  return true;
}

ScopedLevel::ScopedLevel(Level level) : previous_(active()), ok_(setActive(level)) {}

ScopedLevel::~ScopedLevel() {
  if (ok_) setActive(previous_);
}

}  // namespace simd
}  // namespace ground_filter
