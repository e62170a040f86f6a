#!/usr/bin/env bash
# ARM64 check without ARM64 hardware: cross-builds the ROS/PCL-free core and its gtests (cmake
# -DGF_CORE_ONLY=ON: cmake/gf_core_only.cmake) with Debian's g++-aarch64-linux-gnu, runs the gtests
# under qemu-user, then labels the KITTI dev frames with both methods on this x86-64 machine and under
# qemu-aarch64 and compares the labels byte by byte (they must be identical).
#
#   scripts/check_arm64.sh            (needs: g++-aarch64-linux-gnu qemu-user cmake
#                                      googletest libeigen3-dev; the data folder for the labels)
#
# Environment: GF_ARM64_BUILD (build folder, default /tmp/gf_check_arm64), GF_DATA_DIR (data folder,
# default data/, else ../shared/data: scripts/common.sh gf_data_dir), GF_JOBS (default nproc),
# GF_ARM64_RESULTS (folder for gtest XML results; default none), GF_ARM64_FULL=1 (run every gtest, slow under emulation; default: the subset
# below). Exit status: 0 all passed, 1 a test failed or labels differ, 2 a tool is missing.
# Timings under qemu say nothing about an ARM64 CPU's speed: the script reports none.
set -euo pipefail

GF_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck source=scripts/core_only_lib.sh
source "${GF_ROOT}/scripts/core_only_lib.sh"  # DATA, JOBS, SYSROOT, gf_core_only_configure
BUILD="${GF_ARM64_BUILD:-/tmp/gf_check_arm64}"
QEMU=(qemu-aarch64 -L "${SYSROOT}")
start=$(date +%s)

# The cross compiler and the emulator (Debian/Ubuntu packages), installed when missing and root.
if [[ "$(id -u)" == 0 ]] &&
   ! { command -v aarch64-linux-gnu-g++ && command -v qemu-aarch64; } >/dev/null 2>&1; then
  echo "check_arm64: installing g++-aarch64-linux-gnu qemu-user (apt)"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq -o DPkg::Lock::Timeout=900 >/dev/null || true
  apt-get install -y -qq --no-install-recommends -o DPkg::Lock::Timeout=900 \
    g++-aarch64-linux-gnu qemu-user cmake googletest libeigen3-dev >/dev/null || true
fi
for tool in aarch64-linux-gnu-g++ qemu-aarch64 cmake; do
  if ! command -v "${tool}" >/dev/null 2>&1; then
    echo "check_arm64: ${tool} not found (apt-get install g++-aarch64-linux-gnu qemu-user cmake)" >&2
    exit 2
  fi
done
if [[ ! -d /usr/src/googletest || ! -d /usr/include/eigen3 ]]; then
  echo "check_arm64: needs /usr/src/googletest (googletest) and /usr/include/eigen3" >&2
  exit 2
fi
# ccache when there is one, set at the first configure only (a build folder keeps its choice).
launcher() {
  if [[ ! -f "$1/CMakeCache.txt" ]] && command -v ccache >/dev/null 2>&1; then
    echo -DCMAKE_CXX_COMPILER_LAUNCHER=ccache
  fi
}

step() { echo "== check_arm64 [$(($(date +%s) - start)) s] $*"; }

step "cross-build for aarch64 (${BUILD}/arm64)"
gf_core_only_configure check_arm64 "${BUILD}/arm64" \
  -DCMAKE_TOOLCHAIN_FILE="${GF_ROOT}/cmake/aarch64_toolchain.cmake" $(launcher "${BUILD}/arm64") ||
  exit 1
cmake --build "${BUILD}/arm64" -j "${JOBS}"
step "x86-64 build of the label tool (${BUILD}/x86)"
gf_core_only_configure check_arm64 "${BUILD}/x86" $(launcher "${BUILD}/x86") || exit 1
cmake --build "${BUILD}/x86" -j "${JOBS}" --target label_scans

failed=0
# The gtests under emulation. By default a subset (qemu runs them 10-40x slower than native):
# every SIMD-level test except the 5 M-point one, the voxel filter's known-answer tests except
# its large scenes and thread-count sweeps, the working volume, the GPU fallback (no GPU: the
# kd-tree path), the scene generator without its TLS scans, and the kd-tree's exact lists on
# every query path (portable and NEON against brute force and each other). The whole set with
# GF_ARM64_FULL=1.
declare -A filters=(
  [test_simd_levels]='-SimdLevels.FiveMillionPointsAtEveryLevel'
  [test_core]='-*Large*:*Huge*:*Survey*:*Threads*:*NoAllocation*'
  [test_voxel_scale]='-*Large*:*Huge*:*Survey*:*Threads*:*NoAllocation*'
  [test_working_volume]='*'
  [test_gpu_fallback]='*'
  [test_scene_generator]='-*Tls*'
  [test_kdtree_neighbor_search]='*'
)
export GF_TEST_LAUNCHER="${QEMU[*]}"  # SimdLevels.EnvironmentIsReadOncePerProcess starts itself
for t in test_simd_levels test_core test_voxel_scale test_working_volume test_gpu_fallback \
  test_scene_generator test_kdtree_neighbor_search; do
  filter="${filters[${t}]}"
  [[ "${GF_ARM64_FULL:-0}" == 1 ]] && filter='*'
  args=(--gtest_filter="${filter}" --gtest_brief=1)
  if [[ -n "${GF_ARM64_RESULTS:-}" ]]; then
    mkdir -p "${GF_ARM64_RESULTS}"
    args+=(--gtest_output="xml:${GF_ARM64_RESULTS}/arm64-${t}.xml")
  fi
  step "qemu-aarch64 ${t} --gtest_filter=${filter}"
  if ! "${QEMU[@]}" "${BUILD}/arm64/${t}" "${args[@]}"; then
    echo "check_arm64: ${t} FAILED under qemu-aarch64" >&2
    failed=1
  fi
done

# Labels: the KITTI dev frames, x86-64 (its best SIMD level and portable) against aarch64 under
# qemu (its level neon: NEON kd-tree queries, PCA sums and voxel passes; and portable).
frames=()
for f in 0 1 2 3 4 5; do
  [[ -f "${DATA}/semantickitti/seq00/00000${f}.bin" ]] && frames+=("${DATA}/semantickitti/seq00/00000${f}.bin")
done
if [[ ${#frames[@]} -eq 0 ]]; then
  echo "check_arm64: no KITTI frames in ${DATA}/semantickitti/seq00: label comparison not run" >&2
  step "done: gtests $([[ ${failed} == 0 ]] && echo passed || echo FAILED), labels not compared"
  exit "${failed}"
fi
declare -A configs=(
  [voxel]='voxel'
  [voxel_one_plane]='voxel local_planes=false'
  [normal]='normal knn_backend=kdtree threads=2'
)
out="${BUILD}/labels"
rm -rf "${out}"
for name in voxel voxel_one_plane normal; do
  read -r -a cfg <<<"${configs[${name}]}"
  for run in x86 x86_portable arm64 arm64_portable; do
    mkdir -p "${out}/${name}/${run}"
    case "${run}" in
      x86) cmd=(env -u GF_SIMD "${BUILD}/x86/label_scans") ;;
      x86_portable) cmd=(env GF_SIMD=portable "${BUILD}/x86/label_scans") ;;
      arm64) cmd=(env -u GF_SIMD "${QEMU[@]}" "${BUILD}/arm64/label_scans") ;;
      arm64_portable) cmd=(env GF_SIMD=portable "${QEMU[@]}" "${BUILD}/arm64/label_scans") ;;
    esac
    step "labels ${name} ${run}"
    "${cmd[@]}" "${out}/${name}/${run}" "${cfg[@]}" -- "${frames[@]}" | sed 's/, [0-9.]* ms$//'
  done
  for f in "${frames[@]}"; do
    b="$(basename "${f}" .bin).labels"
    ref="${out}/${name}/x86/${b}"
    for run in x86_portable arm64 arm64_portable; do
      gf_compare_labels check_arm64 "${name} ${b}: ${run} vs x86" "${ref}" \
        "${out}/${name}/${run}/${b}" || failed=1
    done
  done
done
step "done: $([[ ${failed} == 0 ]] && echo 'all passed, labels identical' || echo FAILED)"
exit "${failed}"
