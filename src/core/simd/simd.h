// Private to the core: the SIMD level in force, chosen once per process.
#ifndef GROUND_FILTER_SRC_CORE_SIMD_SIMD_H
#define GROUND_FILTER_SRC_CORE_SIMD_SIMD_H

#include <string>

namespace ground_filter {
namespace simd {

/// \brief Instruction-set levels of the hand-vectorised code paths, lowest first. Every level
///        gives the same labels; a level only changes speed.
///
/// kPortable: plain C++ (what any CPU runs); kSse: SSE2/SSE4 intrinsics (x86-64);
/// kNeon: aarch64 (Advanced SIMD is part of it): kd-tree queries, neighbourhood PCA sums,
/// voxel point passes; kAvx2: AVX2 + FMA-free arithmetic (x86-64); kAvx512: AVX-512F (x86-64).
enum class Level : int { kPortable = 0, kSse = 1, kNeon = 2, kAvx2 = 3, kAvx512 = 4 };

/// \brief Lower-case name ("portable", "sse", "neon", "avx2", "avx512").
const char* levelName(Level level);

/// \brief Parses a level name (case-insensitive); false for anything else.
bool parseLevel(const std::string& text, Level* level);

/// \brief Whether this build and this CPU can run `level`.
bool supported(Level level);

/// \brief The highest level this build and CPU run.
Level best();

/// \brief The level a `GF_SIMD` value asks for: best() when `value` is null or empty, or when
///        it is not a level name or names a level this build or CPU cannot run (then `message`,
///        when not null, says why; otherwise it is cleared). active() uses it once.
Level resolveLevel(const char* value, std::string* message);

/// \brief The level in force: `GF_SIMD` (portable | sse | neon | avx2 | avx512, read once per
///        process) or best(). A name that is not a level, or a level this CPU cannot run, is
///        reported once on stderr and best() runs instead (the filter never stops for it).
Level active();

/// \brief True when the level in force includes `level`'s instructions. The x86-64 levels
///        (sse < avx2 < avx512) and neon (aarch64) are two chains above portable: neon
///        allows no x86 level and no x86 level allows neon.
inline bool allows(Level level) {
  const Level a = active();
  if (level == Level::kPortable) return true;
  if (a == Level::kNeon || level == Level::kNeon) return a == level;
  return static_cast<int>(a) >= static_cast<int>(level);
}

/// \brief The CPU model as the OS reports it (/proc/cpuinfo), or "unknown".
std::string cpuModel();

/// \brief One line for tools and logs: "CPU <model>; SIMD <active> (best <best>[, GF_SIMD=..])".
std::string describe();

/// \brief Sets the level in force for this process (tests: every filter under every level the
///        machine has). A level the CPU cannot run is refused: returns false, nothing changes.
bool setActive(Level level);

/// \brief Sets a level for the lifetime of the object, then restores the previous one.
class ScopedLevel {
 public:
  /// \brief ok() tells whether `level` was taken (see setActive()).
  explicit ScopedLevel(Level level);
  ~ScopedLevel();
  ScopedLevel(const ScopedLevel&) = delete;
  ScopedLevel& operator=(const ScopedLevel&) = delete;
  bool ok() const { return ok_; }

 private:
  Level previous_;
  bool ok_;
};

}  // namespace simd
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_SIMD_SIMD_H
