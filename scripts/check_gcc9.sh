#!/usr/bin/env bash
# The compiler floor, GCC 9 (Ubuntu 20.04 / ROS Noetic, JetPack 5 on Jetson), for the ROS-free core
# on x86-64 and aarch64:
#   1. builds the core-only project (-DGF_CORE_ONLY=ON: the core, its gtests and the label tool) with gcc-9 / g++-9 and runs
#      the gtests;
#   2. cross-builds the same with aarch64-linux-gnu-g++-9 (NEON paths included), runs the kd-tree
#      gtest (portable and NEON queries against brute force) under qemu-aarch64 and labels KITTI
#      000000 with both methods there; the labels must equal the x86-64 GCC 9 build's byte for byte.
#
#   bash scripts/check_gcc9.sh [--install]
#     --install   only install what it needs (apt, as root) and exit: g++-9 g++-9-aarch64-linux-gnu
#                 qemu-user cmake googletest libeigen3-dev (Debian 11, Ubuntu 20.04 / 22.04 carry them)
#
# scripts/check_platform.sh runs it in its Debian 11 root (Debian's GCC 9.3.0 packages). Environment:
# GF_GCC9_BUILD (build folder, default /tmp/gf_check_gcc9), GF_DATA_DIR (data folder, default
# data/, else ../shared/data: scripts/common.sh gf_data_dir; the data tests skip without one),
# GF_JOBS (default nproc). Exit status: 0 all passed, 1 a build or test failed or labels differ,
# 2 a tool is missing. Timings under qemu mean nothing; the script reports none.
set -euo pipefail
export PATH="/usr/bin:/bin:/usr/sbin:/sbin:${PATH}"

GF_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck source=scripts/core_only_lib.sh
source "${GF_ROOT}/scripts/core_only_lib.sh"  # DATA, JOBS, SYSROOT, gf_core_only_configure
BUILD="${GF_GCC9_BUILD:-/tmp/gf_check_gcc9}"
PACKAGES=(g++-9 g++-9-aarch64-linux-gnu qemu-user cmake googletest libeigen3-dev)
start=${SECONDS}
step() { echo "== check_gcc9 [$((SECONDS - start)) s] $*"; }

if [[ "${1:-}" == "--install" ]]; then
  [[ "$(id -u)" == 0 ]] || { echo "check_gcc9: --install needs root (apt)" >&2; exit 2; }
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq -o DPkg::Lock::Timeout=900 >/dev/null || true
  apt-get install -y -qq --no-install-recommends -o DPkg::Lock::Timeout=900 "${PACKAGES[@]}" \
    >/dev/null
  exit 0
fi
[[ $# -eq 0 ]] || { echo "usage: $0 [--install]" >&2; exit 2; }
for tool in gcc-9 g++-9 aarch64-linux-gnu-gcc-9 aarch64-linux-gnu-g++-9 qemu-aarch64 cmake; do
  command -v "${tool}" >/dev/null 2>&1 ||
    { echo "check_gcc9: ${tool} not found (bash $0 --install: ${PACKAGES[*]})" >&2; exit 2; }
done
[[ -d /usr/src/googletest && -d /usr/include/eigen3 ]] ||
  { echo "check_gcc9: needs /usr/src/googletest (googletest) and /usr/include/eigen3" >&2; exit 2; }

failed=0
# configure_build <dir> <cmake args...>: the core-only build; the number of compiler warnings is
# reported (not an error).
configure_build() {
  local dir="$1"; shift
  gf_core_only_configure check_gcc9 "${dir}" "$@" || return 1
  grep -E "CXX compiler identification" "${dir}.configure.log" || true
  cmake --build "${dir}" -j "${JOBS}" >"${dir}.build.log" 2>&1 ||
    { grep -E "error|Error" "${dir}.build.log" | head -n 40; return 1; }
  echo "compiler warnings: $(grep -c 'warning:' "${dir}.build.log" || true)"
}
mkdir -p "${BUILD}"

step "x86-64 build with g++-9 (${BUILD}/x86)"
if ! configure_build "${BUILD}/x86" -DCMAKE_C_COMPILER=gcc-9 -DCMAKE_CXX_COMPILER=g++-9; then
  echo "check_gcc9: x86-64 build FAILED" >&2
  exit 1
fi
for t in test_simd_levels test_core test_voxel_scale test_working_volume test_gpu_fallback \
  test_scene_generator test_kdtree_neighbor_search; do
  step "${t}"
  if ! GF_TEST_LAUNCHER='' "${BUILD}/x86/${t}" --gtest_brief=1; then
    echo "check_gcc9: ${t} FAILED (x86-64, GCC 9)" >&2
    failed=1
  fi
done

step "aarch64 cross-build with aarch64-linux-gnu-g++-9 (${BUILD}/arm64)"
if ! GF_AARCH64_CC=aarch64-linux-gnu-gcc-9 GF_AARCH64_CXX=aarch64-linux-gnu-g++-9 \
  configure_build "${BUILD}/arm64" -DCMAKE_TOOLCHAIN_FILE="${GF_ROOT}/cmake/aarch64_toolchain.cmake"; then
  echo "check_gcc9: aarch64 build FAILED" >&2
  exit 1
fi
QEMU=(qemu-aarch64 -L "${SYSROOT}")
step "qemu-aarch64 test_kdtree_neighbor_search"
if ! GF_TEST_LAUNCHER="${QEMU[*]}" "${QEMU[@]}" "${BUILD}/arm64/test_kdtree_neighbor_search" \
  --gtest_brief=1; then
  echo "check_gcc9: test_kdtree_neighbor_search FAILED under qemu-aarch64 (GCC 9)" >&2
  failed=1
fi

frame="${DATA}/semantickitti/seq00/000000.bin"
if [[ ! -f "${frame}" ]]; then
  echo "check_gcc9: no ${frame}: labels not compared" >&2
else
  out="${BUILD}/labels"
  rm -rf "${out}"
  declare -A configs=([voxel]='voxel' [normal]='normal knn_backend=kdtree threads=2')
  for name in voxel normal; do
    read -r -a cfg <<<"${configs[${name}]}"
    mkdir -p "${out}/${name}/x86" "${out}/${name}/arm64"
    step "labels ${name}: x86-64 and aarch64 (qemu), GCC 9"
    env -u GF_SIMD "${BUILD}/x86/label_scans" "${out}/${name}/x86" "${cfg[@]}" -- "${frame}" |
      sed 's/, [0-9.]* ms$//'
    env -u GF_SIMD "${QEMU[@]}" "${BUILD}/arm64/label_scans" "${out}/${name}/arm64" "${cfg[@]}" \
      -- "${frame}" | sed 's/, [0-9.]* ms$//'
    gf_compare_labels check_gcc9 "${name} 000000: aarch64 vs x86-64 (GCC 9)" \
      "${out}/${name}/x86/000000.labels" "${out}/${name}/arm64/000000.labels" || failed=1
  done
fi
step "done: $([[ ${failed} == 0 ]] && echo 'all passed' || echo FAILED)"
exit "${failed}"
