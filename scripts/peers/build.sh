#!/usr/bin/env bash
# Builds the peer drivers (scripts/peers/CMakeLists.txt) into
# ${GF_PEERS_DIR:-~/.cache/ground_filter_peers}/build, outside the package, where
# scripts/peers/run_peers.sh and scripts/speed_table.sh look for drivers:
#   bash scripts/peers/build.sh                # PCL's SAC plane and APMF (libpcl-dev), generic and
#                                              # -march=native
#   bash scripts/peers/build.sh --all   # + Patchwork++, Patchwork, CSF and linefit (or
#       --patchworkpp, --patchwork, --csf, --linefit): clones url-kaist/patchwork-plusplus,
#       LimHyungTae/patchwork, jianboqi/CSF and lorenwel/linefit_ground_segmentation at the
#       pinned commits into ${GF_PEERS_DIR}/src (network, git; PATCHWORKPP_GIT / PATCHWORK_GIT /
#       CSF_GIT / LINEFIT_GIT = a URL or a local clone)
# Prints the build folder. Nothing of a peer's code enters the package: its clone stays in the
# cache folder.
set -euo pipefail
export PATH="/usr/bin:/bin:${PATH}"
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
CACHE="${GF_PEERS_DIR:-${HOME}/.cache/ground_filter_peers}"
BUILD="${CACHE}/build"
# Each peer: git URL (overridable: a mirror or a local clone), the README's pinned commit, the
# paths of it that are needed.
PATCHWORKPP_GIT="${PATCHWORKPP_GIT:-https://github.com/url-kaist/patchwork-plusplus.git}"
PATCHWORK_GIT="${PATCHWORK_GIT:-https://github.com/LimHyungTae/patchwork.git}"
CSF_GIT="${CSF_GIT:-https://github.com/jianboqi/CSF.git}"
LINEFIT_GIT="${LINEFIT_GIT:-https://github.com/lorenwel/linefit_ground_segmentation.git}"
# fetch NAME URL COMMIT PATH...: a clone in ${CACHE}/src/NAME with PATHs at COMMIT.
fetch() {
  local name="$1" url="$2" commit="$3" src="${CACHE}/src/$1"
  shift 3
  if [ ! -d "${src}/.git" ]; then
    mkdir -p "${CACHE}/src"
    rm -rf "${src}"
    git clone -q --no-checkout "${url}" "${src}" ||
      { echo "build.sh: cannot clone ${url} (network? ${name}: set the *_GIT variable)" >&2; exit 1; }
  fi
  git -C "${src}" checkout -q "${commit}" -- "$@" ||
    { echo "build.sh: ${src} has no commit ${commit}" >&2; exit 1; }
}
args=()
for a in "$@"; do
  if [ "$a" = --all ]; then args+=(--patchworkpp --patchwork --csf --linefit); else args+=("$a"); fi
done
extra=()
for a in "${args[@]}"; do
  case "$a" in
    --patchworkpp)  # its C++ core (cpp/) and licence
      fetch patchwork-plusplus "${PATCHWORKPP_GIT}" b608129a4549523067eae461da656195026cd7ca cpp LICENSE
      extra+=("-DGF_PATCHWORKPP_DIR=${CACHE}/src/patchwork-plusplus") ;;
    --patchwork)  # its header-only core (include/), its parameter files and licence
      fetch patchwork "${PATCHWORK_GIT}" 00672c83ca75d0b4a598cd430cfa97393a460059 include config LICENSE
      extra+=("-DGF_PATCHWORK_DIR=${CACHE}/src/patchwork") ;;
    --csf)  # its C++ core (src/), top CMakeLists.txt and licence
      fetch CSF "${CSF_GIT}" e0322a29162c1586a0eae15dc1dd647abce1d11d src CMakeLists.txt LICENSE.txt
      extra+=("-DGF_CSF_DIR=${CACHE}/src/CSF") ;;
    --linefit)  # its core library, its launch parameters and licence
      fetch linefit "${LINEFIT_GIT}" e6b9418cc5756e30e4ea87b11d8792f936a2002a \
        linefit_ground_segmentation linefit_ground_segmentation_ros/launch LICENSE
      extra+=("-DGF_LINEFIT_DIR=${CACHE}/src/linefit") ;;
    *) echo "usage: $0 [--patchworkpp] [--patchwork] [--csf] [--linefit] [--all]" >&2; exit 2 ;;
  esac
done
mkdir -p "${BUILD}" || { echo "build.sh: cannot create ${BUILD}: set GF_PEERS_DIR" >&2; exit 1; }
# A build folder configured from another checkout of the package (CMake refuses to mix two
# sources): configure it afresh from this one.
if [ -f "${BUILD}/CMakeCache.txt" ] &&
  ! grep -qxF "CMAKE_HOME_DIRECTORY:INTERNAL=${HERE}" "${BUILD}/CMakeCache.txt"; then
  echo "build.sh: ${BUILD} was configured from another checkout: configuring it from ${HERE}" >&2
  rm -rf "${BUILD}/CMakeCache.txt" "${BUILD}/CMakeFiles"
fi
if ! cmake -S "${HERE}" -B "${BUILD}" -DCMAKE_BUILD_TYPE=Release "${extra[@]}" \
  >"${BUILD}/configure.log" 2>&1; then
  tail -n 20 "${BUILD}/configure.log" >&2
  echo "build.sh: configure failed (needs cmake, g++, libpcl-dev; Patchwork++: libeigen3-dev," \
    "a C++20 compiler; Patchwork: libtbb-dev, libboost-dev): ${BUILD}/configure.log" >&2
  exit 1
fi
if ! cmake --build "${BUILD}" -j"${GF_JOBS:-2}" >"${BUILD}/build.log" 2>&1; then
  grep -m 20 -E "error|Error" "${BUILD}/build.log" >&2 || true
  echo "build.sh: build failed: ${BUILD}/build.log" >&2
  exit 1
fi
echo "${BUILD}"
