#!/usr/bin/env bash
# Runs every test (gtest for the core, rostest for the nodelets, launch file checks), then the
# packaging checks of scripts/ci_checks.sh (focal-like build without nanoflann and with the
# cuda/ guard forced, C++14 headers, CUDA architecture defaults, an unresolvable hostname).
# Installs missing packages, builds in .ws/, exits non-zero on any failure, ends with a summary
# line (skipped counted apart).
# GF_CI_EXTRA=0 leaves the packaging checks out.
# Under CI (CI=true) it also runs the README's commands in a Debian 11 root
# (scripts/check_platform.sh bullseye; GF_CHECK_PLATFORM=0 leaves it out, =1 runs it outside CI,
# GF_CHECK_PLATFORM_ARGS: default --quick = build, core gtests, one rostest, demo, installed-ROS
# checks; GF_CHECK_PLATFORM_ARGS= (empty) runs every test there) and the ARM64 check
# scripts/check_arm64.sh when that script exists (GF_CHECK_ARM64=0 leaves it out).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
source "${GF_ROOT}/scripts/ci_checks.sh"
gf_install_deps
gf_ros_env  # ROS on loopback unless the caller's ROS_HOSTNAME / ROS_MASTER_URI resolve
gf_build
cd "${GF_WS}"
results="${GF_WS}/build/test_results"
rm -rf "${results}"
# Test binaries build in parallel; the tests themselves run one at a time (rostests share CPUs).
catkin_make tests -j"$(nproc 2>/dev/null || echo 2)"
set +e
catkin_make run_tests -j1 2>&1 | tee "${GF_WS}/run_tests.log"
build_rc=${PIPESTATUS[0]}
# Core gtests under ASan + UBSan, 60 s of fuzzing per filter, 2 + 1 minutes of soak; each writes
# JUnit XML next to catkin's, so the summary below counts them.
t0=${SECONDS}
bash "${GF_ROOT}/scripts/sanitize.sh" --results "${results}/sanitize"
bash "${GF_ROOT}/scripts/fuzz.sh" 60 --results "${results}/fuzz"
bash "${GF_ROOT}/scripts/soak.sh" 2 --results "${results}/soak"
# The same with the scan published inside the manager (a driver's nodelet: no serialisation).
bash "${GF_ROOT}/scripts/soak.sh" 1 --driver-in-manager --results "${results}/soak_driver"
echo "[ci] sanitize + fuzz + soak: $((SECONDS - t0)) s"
echo "[ci] catkin tests done after ${SECONDS} s"
if [ "${GF_CI_EXTRA:-1}" != "0" ]; then
  for step in gf_check_focal_like gf_check_cuda_archs gf_check_container; do
    t0=${SECONDS}
    "${step}" "${results}/ground_filter"
    echo "[ci] ${step}: $((SECONDS - t0)) s"
  done
fi
if [ "${CI:-false}" = "true" ]; then ci_default=1; else ci_default=0; fi
if [ "${GF_CHECK_PLATFORM:-${ci_default}}" = "1" ]; then
  t0=${SECONDS}
  # shellcheck disable=SC2086
  bash "${GF_ROOT}/scripts/check_platform.sh" bullseye ${GF_CHECK_PLATFORM_ARGS---quick} \
    2>&1 | tee "${GF_WS}/check_platform.log"
  platform_rc=${PIPESTATUS[0]}
  echo "[ci] check_platform bullseye: $((SECONDS - t0)) s (exit ${platform_rc})"
  # One result per step (install, demo, tests, existing ROS); the root's own summary line in it.
  while read -r _ name status secs; do
    python3 "${GF_ROOT}/scripts/junit_result.py" "${results}/ci-bullseye_${name}.xml" bullseye \
      "${name}" "${status}" "${secs}; $(grep -E '^Summary:|^CHECK ' "${GF_WS}/check_platform.log" |
      tr '\n' ' ')" >/dev/null
  done < <(grep '^RESULT ' "${GF_WS}/check_platform.log")
  if ! grep -q '^RESULT ' "${GF_WS}/check_platform.log"; then
    python3 "${GF_ROOT}/scripts/junit_result.py" "${results}/ci-bullseye.xml" bullseye \
      check_platform failed "no result: $(tail -n 10 "${GF_WS}/check_platform.log")" >/dev/null
  fi
fi
# ---- ARM64 hook: scripts/check_arm64.sh is written elsewhere; run when present.
if [ "${GF_CHECK_ARM64:-${ci_default}}" = "1" ] && [ -f "${GF_ROOT}/scripts/check_arm64.sh" ]; then
  t0=${SECONDS}
  bash "${GF_ROOT}/scripts/check_arm64.sh" 2>&1 | tee "${GF_WS}/check_arm64.log"
  arm64_rc=${PIPESTATUS[0]}
  echo "[ci] check_arm64: $((SECONDS - t0)) s (exit ${arm64_rc})"
  python3 "${GF_ROOT}/scripts/junit_result.py" "${results}/ci-arm64.xml" arm64 check_arm64 \
    "$([ "${arm64_rc}" = 0 ] && echo passed || echo failed)" \
    "exit ${arm64_rc}: $(tail -n 5 "${GF_WS}/check_arm64.log" | tr '\n' ' ')" >/dev/null
fi
python3 "${GF_ROOT}/scripts/test_summary.py" "${results}"
summary_rc=$?
set -e
if [ "${build_rc}" != "0" ]; then
  echo "catkin_make run_tests exited ${build_rc} (a test target failed to build or run)"
  exit 1
fi
exit "${summary_rc}"
