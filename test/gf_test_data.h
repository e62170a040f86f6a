// Test data guard: tests that read the data folder (GF_DATA_DIR of the build: $GF_DATA_DIR, else
// data/, else ../shared/data) skip (with the reason, counted as skipped by catkin and
// scripts/test_summary.py) when the data is not there, e.g. in a user's clone.
#ifndef GROUND_FILTER_TEST_GF_TEST_DATA_H_
#define GROUND_FILTER_TEST_GF_TEST_DATA_H_

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <string>

namespace gf_test {

/// \brief True when `path` exists (file or directory).
inline bool dataExists(const std::string& path) {
  struct stat st;
  return ::stat(path.c_str(), &st) == 0;
}

}  // namespace gf_test

/// Skips the current test when `path` (a data file or folder) is missing.
#define GF_SKIP_WITHOUT_DATA(path)                                                           \
  do {                                                                                       \
    const std::string gf_data_path_ = (path);                                                \
    if (!gf_test::dataExists(gf_data_path_)) {                                               \
      GTEST_SKIP() << "data not found: " << gf_data_path_                                    \
                   << " (run scripts/get_data.sh, or set GF_DATA_DIR, and configure again)"; \
    }                                                                                        \
  } while (0)

#endif  // GROUND_FILTER_TEST_GF_TEST_DATA_H_
