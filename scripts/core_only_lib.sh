# Sourced by scripts/check_arm64.sh and scripts/check_gcc9.sh: what both need to build the core
# with -DGF_CORE_ONLY=ON (CMakeLists.txt, cmake/gf_core_only.cmake) for two architectures and
# compare their labels. Sets DATA (the data folder; none: data/, and the data tests skip naming
# it), JOBS ($GF_JOBS, default nproc) and SYSROOT (aarch64's libraries for qemu-aarch64 -L).
# shellcheck source=scripts/common.sh
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
DATA="$(gf_data_dir --or-repo)"
JOBS="${GF_JOBS:-$(nproc 2>/dev/null || echo 2)}"
SYSROOT=/usr/aarch64-linux-gnu

# gf_core_only_configure <tool> <dir> <cmake args...>: configures <dir> as this checkout's
# core-only build (a folder configured from another checkout, which CMake refuses, is started
# afresh); the log in <dir>.configure.log, printed on failure.
gf_core_only_configure() {
  local tool="$1" dir="$2"
  shift 2
  if [[ -f "${dir}/CMakeCache.txt" ]] &&
     ! grep -qxF "CMAKE_HOME_DIRECTORY:INTERNAL=${GF_ROOT}" "${dir}/CMakeCache.txt"; then
    echo "${tool}: ${dir} was configured from another checkout: starting it afresh"
    rm -rf "${dir}"
  fi
  mkdir -p "$(dirname "${dir}")"
  cmake -S "${GF_ROOT}" -B "${dir}" -DGF_CORE_ONLY=ON -DCMAKE_BUILD_TYPE=Release \
    -DGF_DATA_DIR="${DATA}" "$@" >"${dir}.configure.log" 2>&1 ||
    { cat "${dir}.configure.log"; return 1; }
}

# The label files of two builds compared byte for byte.
#   gf_compare_labels <tool> <what> <reference file> <file>
# prints "labels <what>: N of M differ" and returns 0 only when both files exist, have the same
# length and N is 0 (a missing or shorter file is named on stderr with <tool>).
gf_compare_labels() {
  local tool="$1" what="$2" ref="$3" got="$4" n
  if [[ ! -s "${ref}" || ! -s "${got}" ]] || [[ $(stat -c %s "${ref}") != $(stat -c %s "${got}") ]]; then
    echo "${tool}: ${what}: labels missing or of another length" >&2
    return 1
  fi
  n=$(cmp -l "${ref}" "${got}" | wc -l || true)
  echo "labels ${what}: ${n} of $(stat -c %s "${ref}") differ"
  [[ "${n}" == 0 ]]
}
