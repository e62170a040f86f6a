#include "cli_args.h"

#include <sys/stat.h>

#include <algorithm>
#include <cstdlib>
#include <exception>
#include <fstream>
#include <iostream>

#include "simd/simd.h"

namespace ground_filter {
namespace cli {

namespace {

std::string trim(const std::string& s) {
  const std::size_t b = s.find_first_not_of(" \t\r");
  if (b == std::string::npos) return "";
  const std::size_t e = s.find_last_not_of(" \t\r");
  return s.substr(b, e - b + 1);
}

}  // namespace

int runTool(const char* tool, const std::function<int()>& body) {
  try {
    return body();
  } catch (const UsageError& e) {
    std::cerr << tool << ": " << e.what() << "\n(try --help)" << std::endl;
    return 2;
  } catch (const std::exception& e) {
    std::cerr << tool << ": error: " << e.what() << std::endl;
    return 1;
  }
}

std::string simdDescription() { return simd::describe(); }

namespace {
bool isDirectory(const std::string& path) {
  struct stat st;
  return ::stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode);
}
}  // namespace

std::string dataDir() {
  const char* env = std::getenv("GF_DATA_DIR");
  if (env && *env) {
    if (!isDirectory(env)) {
      throw std::runtime_error(std::string("GF_DATA_DIR=") + env +
                               " is not a folder: fix or unset it (bash scripts/get_data.sh "
                               "--dest DIR fills a folder)");
    }
    return env;
  }
  for (const char* d : {GF_REPO_DIR "/data", GF_REPO_DIR "/../shared/data"}) {
    if (isDirectory(d)) return d;
  }
  throw std::runtime_error("no data: run bash " GF_REPO_DIR
                           "/scripts/get_data.sh (fills " GF_REPO_DIR
                           "/data), set GF_DATA_DIR, or name the input files");
}

bool ArgCursor::next() {
  if (i_ + 1 >= argc_) return false;
  ++i_;
  option_ = argv_[i_];
  if (option_ == "--help" || option_ == "-h") {
    std::cout << usage_;
    std::exit(0);
  }
  has_inline_ = false;
  inline_value_.clear();
  const std::size_t eq = option_.find('=');
  if (option_.rfind("--", 0) == 0 && eq != std::string::npos) {
    inline_value_ = option_.substr(eq + 1);
    option_ = option_.substr(0, eq);
    has_inline_ = true;
  }
  return true;
}

std::string ArgCursor::value() {
  if (has_inline_) return inline_value_;
  if (i_ + 1 >= argc_) throw UsageError(option_ + " needs a value");
  return argv_[++i_];
}

std::string ArgCursor::path() const {
  if (option_.size() > 1 && option_[0] == '-') {
    throw UsageError("unknown option '" + option_ + "'");
  }
  return argv_[i_];
}

bool ArgCursor::takeInt(const std::vector<IntOption>& options) {
  for (const IntOption& o : options) {
    if (option_ == o.name) {
      *o.value = parseIntOption(option_, value(), o.lo, o.hi);
      return true;
    }
  }
  return false;
}

void parseCommandLine(int argc, char** argv, const char* usage, const std::vector<IntOption>& ints,
                      ParamSettings* sets, std::vector<std::string>* paths,
                      const std::function<bool(ArgCursor*)>& other) {
  ArgCursor args(argc, argv, usage);
  while (args.next()) {
    if (args.takeInt(ints)) continue;
    if (sets && args.option() == "--set") {
      sets->push_back(parseSetting(args.value()));
    } else if (!other || !other(&args)) {
      paths->push_back(args.path());
    }
  }
}

void parseCommandLine(int argc, char** argv, const char* usage, const std::vector<IntOption>& ints,
                      SetsAndPaths* out, const std::function<bool(ArgCursor*)>& other) {
  parseCommandLine(argc, argv, usage, ints, &out->settings, &out->paths, other);
}

bool FilterArgs::consume(ArgCursor* args) {
  const std::string& opt = args->option();
  if (opt == "--method") {
    method = args->value();
  } else if (opt == "--set") {
    from_set.push_back(parseSetting(args->value()));
  } else if (opt == "--params") {
    const std::string path = args->value();
    try {
      const ParamSettings s = loadParamsFile(path);
      from_file.insert(from_file.end(), s.begin(), s.end());
    } catch (const std::runtime_error& e) {
      throw UsageError(e.what());
    }
  } else {
    return false;
  }
  return true;
}

ParamSettings FilterArgs::settings() const {
  ParamSettings s = from_file;
  s.insert(s.end(), from_set.begin(), from_set.end());
  return s;
}

std::pair<std::string, std::string> parseSetting(const std::string& kv) {
  const std::size_t eq = kv.find('=');
  if (eq == std::string::npos || eq == 0) {
    throw UsageError("--set expects NAME=VALUE, got '" + kv + "'");
  }
  return {kv.substr(0, eq), kv.substr(eq + 1)};
}

int parseIntOption(const std::string& opt, const std::string& v, int lo, int hi) {
  char* end = nullptr;
  const long n = std::strtol(v.c_str(), &end, 10);
  if (v.empty() || *end != '\0' || n < lo || n > hi) {
    throw UsageError(opt + " expects an integer in [" + std::to_string(lo) + ", " +
                     std::to_string(hi) + "], got '" + v + "'");
  }
  return static_cast<int>(n);
}

std::vector<int> parseIntList(const std::string& opt, const std::string& v, int lo, int hi) {
  std::vector<int> out;
  std::size_t start = 0;
  while (start <= v.size()) {
    const std::size_t comma = std::min(v.find(',', start), v.size());
    out.push_back(parseIntOption(opt, v.substr(start, comma - start), lo, hi));
    start = comma + 1;
  }
  return out;
}

ParamSettings loadParamsFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open parameter file");
  ParamSettings out;
  std::string line;
  for (int no = 1; std::getline(in, line); ++no) {
    const std::string where = path + ":" + std::to_string(no) + ": ";
    // A '#' starts a comment unless it is inside quotes (values here never need one).
    const std::size_t hash = line.find('#');
    const std::string body = trim(hash == std::string::npos ? line : line.substr(0, hash));
    if (body.empty()) continue;
    if (line.find_first_not_of(" \t") != 0) {
      throw std::runtime_error(where + "nested keys are not parameters (flat 'name: value' only)");
    }
    const std::size_t colon = body.find(':');
    if (colon == std::string::npos || colon == 0) {
      throw std::runtime_error(where + "expected 'name: value', got '" + body + "'");
    }
    const std::string name = trim(body.substr(0, colon));
    std::string value = trim(body.substr(colon + 1));
    if (value.size() >= 2 && (value.front() == '"' || value.front() == '\'') &&
        value.back() == value.front()) {
      value = value.substr(1, value.size() - 2);
    }
    if (value.empty() || value[0] == '[' || value[0] == '{' || value[0] == '|' || value[0] == '>') {
      throw std::runtime_error(where + "parameter '" + name + "' needs a scalar value");
    }
    for (const auto& kv : out) {
      if (kv.first == name) throw std::runtime_error(where + "parameter '" + name + "' repeated");
    }
    out.emplace_back(name, value);
  }
  return out;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

}  // namespace cli
}  // namespace ground_filter
