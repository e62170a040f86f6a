#!/usr/bin/env bash
# Fuzzes the serialised-PointCloud2 path (test/fuzz_point_cloud2.cpp: deserialise -> validate ->
# view -> working volume -> filter -> split -> labelled cloud) with libFuzzer under ASan + UBSan.
#   scripts/fuzz.sh [SECONDS_PER_METHOD] [--results DIR] [--methods "voxel normal"]
# Default 60 s per method. Seeds: test/fuzz_corpus/ (regenerate with test/fuzz_make_corpus.py);
# the growing working corpus stays in .ws_asan/fuzz_work/ (git-ignored). A crash leaves its
# input in .ws_asan/fuzz_artifacts/METHOD/: fix the bug, then add the file to test/fuzz_corpus/
# as crash-NAME so every later run replays it. One JUnit case per method and per corpus replay.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
SECONDS_PER_METHOD=60
RESULTS="${GF_ROOT}/.ws_asan/test_results"
METHODS="voxel normal"
while [ $# -gt 0 ]; do
  case "$1" in
    --results) RESULTS="$2"; shift 2 ;;
    --methods) METHODS="$2"; shift 2 ;;
    [0-9]*) SECONDS_PER_METHOD="$1"; shift ;;
    *) echo "usage: $0 [SECONDS_PER_METHOD] [--results DIR] [--methods LIST]" >&2; exit 2 ;;
  esac
done
mkdir -p "${RESULTS}"
JUNIT="${GF_ROOT}/scripts/sanitize_junit.py"
bash "${GF_ROOT}/scripts/sanitize.sh" --build-only --results "${RESULTS}" || exit 1
FUZZ="${GF_ROOT}/.ws_asan/fuzz_point_cloud2"
SEEDS="${GF_ROOT}/test/fuzz_corpus"
export ASAN_OPTIONS="detect_leaks=1:halt_on_error=1"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
# Inputs up to 64 KB: a few thousand points, enough for every code path, fast per run.
# -timeout: the slowest valid inputs known are a few thousand points scattered over 2 km (the
# airborne raster then holds 16 cells a point, filled 4 x 50 Laplace sweeps): 0.3 s in a release
# build, 9-14 s under ASan + UBSan + coverage at -O1 on 2 cores (test/fuzz_corpus/
# slow-sparse-scatter-2km, 2 000 points, 2.5 s). 60 s leaves room for slower CI machines; a hang
# still fails.
OPTS=(-max_len=65536 -timeout=60 -rss_limit_mb=2048 -print_final_stats=1)
rc_all=0
for method in ${METHODS}; do
  work="${GF_ROOT}/.ws_asan/fuzz_work/${method}"
  art="${GF_ROOT}/.ws_asan/fuzz_artifacts/${method}"
  mkdir -p "${work}" "${art}"
  log="${GF_ROOT}/.ws_asan/fuzz_${method}.log"
  # 1. Replay every seed and every past crash once.
  set +e
  GF_FUZZ_METHOD="${method}" nice -n 5 "${FUZZ}" "${OPTS[@]}" -runs=0 \
    -artifact_prefix="${art}/" "${SEEDS}" > "${log}.replay" 2>&1
  rc=$?
  set -e
  if [ "${rc}" = 0 ]; then
    python3 "${JUNIT}" "${RESULTS}/fuzz_${method}_corpus.xml" fuzz "${method}_corpus_replay" pass \
      "$(grep -m1 -E 'INITED|DONE' "${log}.replay" || true)"
  else
    python3 "${JUNIT}" "${RESULTS}/fuzz_${method}_corpus.xml" fuzz "${method}_corpus_replay" fail \
      "exit ${rc}: $(grep -m5 -E 'ERROR: |runtime error|invariant|Test unit written' "${log}.replay")"
    rc_all=1
  fi
  # 2. Fuzz for the given time.
  set +e
  GF_FUZZ_METHOD="${method}" nice -n 5 "${FUZZ}" "${OPTS[@]}" \
    -max_total_time="${SECONDS_PER_METHOD}" -artifact_prefix="${art}/" "${work}" "${SEEDS}" \
    > "${log}" 2>&1
  rc=$?
  set -e
  stats="$(grep -E '^stat::number_of_executed_units|^stat::peak_rss_mb' "${log}" | tr '\n' ' ')"
  cov="$(grep -E '#[0-9]+.*(DONE|pulse)' "${log}" | tail -1)"
  if [ "${rc}" = 0 ]; then
    echo "[fuzz] ${method}: ${SECONDS_PER_METHOD} s, no crash; ${stats}; ${cov}"
    python3 "${JUNIT}" "${RESULTS}/fuzz_${method}.xml" fuzz "${method}_${SECONDS_PER_METHOD}s" pass \
      "${stats} ${cov}"
  else
    echo "[fuzz] ${method}: FAILED (exit ${rc}), log ${log}:"
    grep -m10 -E 'ERROR: |runtime error|invariant|Test unit written|SUMMARY' "${log}" || tail -20 "${log}"
    python3 "${JUNIT}" "${RESULTS}/fuzz_${method}.xml" fuzz "${method}_${SECONDS_PER_METHOD}s" fail \
      "exit ${rc}: $(grep -m5 -E 'ERROR: |runtime error|invariant|Test unit written' "${log}")"
    rc_all=1
  fi
done
exit "${rc_all}"
