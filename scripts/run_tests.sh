#!/usr/bin/env bash
# Runs every test (gtest for the core, rostest for the nodelets, launch file checks).
# Installs missing packages, builds in .ws/, exits non-zero on any failure, ends with a summary line.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
gf_install_deps
gf_build
cd "${GF_WS}"
rm -rf "${GF_WS}/build/test_results"
# Test binaries build in parallel; the tests themselves run one at a time (rostests share CPUs).
catkin_make tests -j"$(nproc 2>/dev/null || echo 2)"
set +e
catkin_make run_tests -j1 2>&1 | tee "${GF_WS}/run_tests.log"
build_rc=${PIPESTATUS[0]}
# Issue 12: core gtests under ASan + UBSan, 60 s of fuzzing per filter, a 2-minute soak; each
# writes JUnit XML next to catkin's, so the summary below counts them.
bash "${GF_ROOT}/scripts/sanitize.sh" --results "${GF_WS}/build/test_results/sanitize"
bash "${GF_ROOT}/scripts/fuzz.sh" 60 --results "${GF_WS}/build/test_results/fuzz"
bash "${GF_ROOT}/scripts/soak.sh" 2 --results "${GF_WS}/build/test_results/soak"
python3 "${GF_ROOT}/scripts/test_summary.py" "${GF_WS}/build/test_results"
summary_rc=$?
set -e
if [ "${build_rc}" != "0" ]; then
  echo "catkin_make run_tests exited ${build_rc} (a test target failed to build or run)"
  exit 1
fi
exit "${summary_rc}"
