// Command-line helpers shared by the tools (eval, benchmark, knn and peer benchmarks): main()'s
// error handling, option cursor with --name=value support, --set NAME=VALUE, --params FILE (flat
// YAML), integers, the default data folder, timing.
#ifndef GROUND_FILTER_TOOLS_CLI_ARGS_H
#define GROUND_FILTER_TOOLS_CLI_ARGS_H

#include <chrono>
#include <functional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "common/threads_timing.h"
#include "ground_filter/ground_filter.h"

// The checkout: its data/ (scripts/get_data.sh) and ../shared/data are the default data folders
// (cli::dataDir()). The build sets it (CMakeLists.txt, target ground_filter_cli).
#ifndef GF_REPO_DIR
#define GF_REPO_DIR "."
#endif
// The default data folders as the tools' --help texts name them.
#define GF_DEFAULT_DATA_DIR GF_REPO_DIR "/data, else " GF_REPO_DIR "/../shared/data"

namespace ground_filter {
namespace cli {

/// \brief A bad command line (the tools exit with status 2).
struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// \brief A tool's main(): returns `body()`; a UsageError prints "TOOL: message (try --help)"
///        and gives 2, any other exception "TOOL: error: message" and gives 1.
int runTool(const char* tool, const std::function<int()>& body);

/// \brief Folder of the default inputs, the rule of scripts/common.sh gf_data_dir: $GF_DATA_DIR
///        when set and not empty (a std::runtime_error when it is not a folder), else
///        GF_REPO_DIR/data when it exists, else GF_REPO_DIR/../shared/data when it exists, else
///        a std::runtime_error saying to run scripts/get_data.sh.
std::string dataDir();

/// \brief One header line for timings: the CPU model and the SIMD path taken (the level in
///        force, GF_SIMD when set), e.g. "CPU AMD EPYC ...; SIMD avx2 (best avx512, GF_SIMD=avx2)".
std::string simdDescription();

/// \brief An integer option: its name, where it goes and its range.
struct IntOption {
  const char* name;  ///< e.g. "--repeat"
  int* value;        ///< set from the option's value
  int lo, hi;        ///< accepted range (inclusive)
};

/// \brief Walks argv; splits `--name=value` into option and inline value; answers `--help`.
class ArgCursor {
 public:
  /// \brief Starts before argv[1]; `usage` is the tool's --help text.
  ArgCursor(int argc, char** argv, const char* usage) : argc_(argc), argv_(argv), usage_(usage) {}
  /// \brief Moves to the next argument; false when there is none. `--help` or `-h` prints the
  ///        usage text and exits with status 0.
  bool next();
  /// \brief The current argument without an inline `=value` of a `--` option.
  const std::string& option() const { return option_; }
  /// \brief The current argument exactly as given.
  const char* raw() const { return argv_[i_]; }
  /// \brief The option's value: the inline one, else the next argument.
  /// \throws UsageError when there is none.
  std::string value();
  /// \brief The current argument as a PATH (operand); a lone "-" is one.
  /// \throws UsageError when it looks like an option (no tool option matched it).
  std::string path() const;
  /// \brief Takes the current option when it is one of `options` (parseIntOption()).
  /// \returns false when it is none of them.
  /// \throws UsageError for a missing or bad value.
  bool takeInt(const std::vector<IntOption>& options);

 private:
  int argc_;
  char** argv_;
  const char* usage_;
  int i_ = 0;
  std::string option_;
  std::string inline_value_;
  bool has_inline_ = false;
};

/// \brief Walks the command line: `--help` prints `usage` and exits; the integer options `ints`;
///        `--set NAME=VALUE` into `*sets` when `sets` is given; any other option goes to
///        `other(cursor)` (when given), which returns false for one it does not know; the
///        remaining arguments are PATHs, appended to `*paths`.
/// \throws UsageError for an unknown option or a missing or bad value.
void parseCommandLine(int argc, char** argv, const char* usage, const std::vector<IntOption>& ints,
                      ParamSettings* sets, std::vector<std::string>* paths,
                      const std::function<bool(ArgCursor*)>& other = nullptr);

/// \brief The part of a tool's options that parseCommandLine() fills besides the integers: the
///        `--set NAME=VALUE` settings and the PATH operands (a tool's Options derives from it).
struct SetsAndPaths {
  ParamSettings settings;          ///< --set, in command-line order
  std::vector<std::string> paths;  ///< the operands, in order
};

/// \brief parseCommandLine() with `--set` into out->settings and the PATHs into out->paths.
/// \throws UsageError for an unknown option or a missing or bad value.
void parseCommandLine(int argc, char** argv, const char* usage, const std::vector<IntOption>& ints,
                      SetsAndPaths* out, const std::function<bool(ArgCursor*)>& other = nullptr);

/// \brief The filter options every tool shares: `--method NAME`, `--params FILE` and
///        `--set NAME=VALUE` (a `--set` overrides the file whatever their order).
struct FilterArgs {
  std::string method = "voxel";  ///< --method (default voxel)
  ParamSettings from_file;       ///< --params, in file order
  ParamSettings from_set;        ///< --set, in command-line order

  /// \brief Takes the cursor's current option when it is one of the three.
  /// \returns false when it is another option.
  /// \throws UsageError for a bad value or an unreadable/malformed parameter file.
  bool consume(ArgCursor* args);
  /// \brief The file's settings followed by the --set ones.
  ParamSettings settings() const;
};

/// \brief Splits `NAME=VALUE` of `--set`.
/// \throws UsageError when there is no '=' or NAME is empty.
std::pair<std::string, std::string> parseSetting(const std::string& kv);

/// \brief Integer value of option `opt` in [lo, hi].
/// \throws UsageError otherwise.
int parseIntOption(const std::string& opt, const std::string& v, int lo, int hi);

/// \brief Comma-separated integers of option `opt`, each in [lo, hi] (e.g. `--threads 1,2`).
/// \throws UsageError for an empty or bad entry.
std::vector<int> parseIntList(const std::string& opt, const std::string& v, int lo, int hi);

/// \brief Reads a parameter file: flat YAML `name: value` lines (the files of config/ and of
///        `params_file:=`), `#` comments and blank lines allowed; quotes around a value are
///        removed. Order is kept.
/// \throws std::runtime_error naming the file and line for anything else (nesting, lists, a
///         repeated name) or when the file cannot be read.
ParamSettings loadParamsFile(const std::string& path);

/// \brief Median of `v` (mean of the two middle values for an even count; 0 for none).
double median(std::vector<double> v);

/// \brief Milliseconds since `t0` on the steady clock (the core's one definition).
using ::ground_filter::msSince;

}  // namespace cli
}  // namespace ground_filter

#endif  // GROUND_FILTER_TOOLS_CLI_ARGS_H
