#!/usr/bin/env bash
# Builds the ROS-free core with clang and -fsanitize=address,undefined in .ws_asan/ (git-ignored;
# cmake -DGF_CORE_ONLY=ON -DGF_SANITIZE=ON: cmake/gf_core_only.cmake) and runs its gtests there;
# results as JUnit XML for scripts/test_summary.py.
#   scripts/sanitize.sh [--results DIR] [--build-only]
# DIR defaults to .ws_asan/test_results. The libFuzzer target of scripts/fuzz.sh is built here too.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
RESULTS="${GF_ROOT}/.ws_asan/test_results"
BUILD_ONLY=0
while [ $# -gt 0 ]; do
  case "$1" in
    --results) RESULTS="$2"; shift 2 ;;
    --build-only) BUILD_ONLY=1; shift ;;
    *) echo "usage: $0 [--results DIR] [--build-only]" >&2; exit 2 ;;
  esac
done
SAN_BUILD="${GF_ROOT}/.ws_asan"
JUNIT="${GF_ROOT}/scripts/sanitize_junit.py"

# Build. A failure is reported as a failed test case, not as a silent skip.
# A folder configured from another source (CMake refuses it) is built afresh (its test binaries
# too: the loop below runs every asan_test_*; the fuzz corpus and artifacts stay).
if [ -f "${SAN_BUILD}/CMakeCache.txt" ] &&
   ! grep -qxF "CMAKE_HOME_DIRECTORY:INTERNAL=${GF_ROOT}" "${SAN_BUILD}/CMakeCache.txt"; then
  rm -rf "${SAN_BUILD:?}/CMakeCache.txt" "${SAN_BUILD}/CMakeFiles" "${SAN_BUILD}"/asan_test_*
fi
mkdir -p "${SAN_BUILD}" "${RESULTS}"
build_log="${SAN_BUILD}/build.log"
if ! (cd "${SAN_BUILD}" &&
      CXX=clang++ cmake -S "${GF_ROOT}" -B . -DGF_CORE_ONLY=ON -DGF_SANITIZE=ON \
        -DCMAKE_BUILD_TYPE=None \
        ${CMAKE_CXX_COMPILER_LAUNCHER:+-DCMAKE_CXX_COMPILER_LAUNCHER=${CMAKE_CXX_COMPILER_LAUNCHER}} \
        > "${build_log}" 2>&1 &&
      nice -n 5 cmake --build . -j"$(nproc 2>/dev/null || echo 2)" >> "${build_log}" 2>&1); then
  tail -30 "${build_log}"
  python3 "${JUNIT}" "${RESULTS}/sanitize_build.xml" sanitize build fail "$(tail -30 "${build_log}")"
  echo "[sanitize] build failed (log: ${build_log})"
  exit 1
fi
python3 "${JUNIT}" "${RESULTS}/sanitize_build.xml" sanitize build pass ""
[ "${BUILD_ONLY}" = 1 ] && exit 0

export ASAN_OPTIONS="detect_leaks=1:abort_on_error=0:halt_on_error=1"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
rc_all=0
mkdir -p "${SAN_BUILD}/logs"
for bin in "${SAN_BUILD}"/asan_test_*; do
  [ -f "${bin}" ] && [ -x "${bin}" ] || continue  # test binaries only
  name="$(basename "${bin}")"
  log="${SAN_BUILD}/logs/${name}.log"
  set +e
  nice -n 5 "${bin}" --gtest_output="xml:${RESULTS}/${name}.xml" > "${log}" 2>&1
  rc=$?
  set -e
  # gtest's XML says nothing about a sanitizer report at exit (leaks) or an abort mid-run.
  if [ "${rc}" = 0 ]; then
    python3 "${JUNIT}" "${RESULTS}/${name}_exit.xml" sanitize "${name}_exit" pass ""
    echo "[sanitize] ${name}: ok"
  else
    python3 "${JUNIT}" "${RESULTS}/${name}_exit.xml" sanitize "${name}_exit" fail \
      "exit ${rc}: $(grep -m5 -E 'ERROR: |runtime error|FAILED' "${log}" || tail -20 "${log}")"
    echo "[sanitize] ${name}: FAILED (exit ${rc}, log ${log})"
    rc_all=1
  fi
done
exit "${rc_all}"
