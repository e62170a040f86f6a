#!/usr/bin/env bash
# Builds the peer drivers (scripts/peers/CMakeLists.txt) into
# ${GF_PEERS_DIR:-~/.cache/ground_filter_peers}/build, outside the package, where
# scripts/peers/run_peers.sh and scripts/speed_table.sh look for drivers:
#   bash scripts/peers/build.sh                # PCL's SAC plane (libpcl-dev), generic and -march=native
#   bash scripts/peers/build.sh --patchworkpp  # + Patchwork++: clones url-kaist/patchwork-plusplus at
#                                              #   the pinned commit into ${GF_PEERS_DIR}/src (network,
#                                              #   git; PATCHWORKPP_GIT=URL or path for a mirror)
# Prints the build folder. Nothing of a peer's code enters the package: its clone stays in the
# cache folder. linefit's and CSF's drivers are not built here (scripts/peers/README.md).
set -euo pipefail
export PATH="/usr/bin:/bin:${PATH}"
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
CACHE="${GF_PEERS_DIR:-${HOME}/.cache/ground_filter_peers}"
BUILD="${CACHE}/build"
PATCHWORKPP_GIT="${PATCHWORKPP_GIT:-https://github.com/url-kaist/patchwork-plusplus.git}"
PATCHWORKPP_COMMIT=b608129a4549523067eae461da656195026cd7ca  # the README's rows
extra=()
for a in "$@"; do
  case "$a" in
    --patchworkpp)
      src="${CACHE}/src/patchwork-plusplus"
      if [ ! -d "${src}/.git" ]; then
        mkdir -p "${CACHE}/src"
        rm -rf "${src}"
        git clone -q --no-checkout "${PATCHWORKPP_GIT}" "${src}" ||
          { echo "build.sh: cannot clone ${PATCHWORKPP_GIT} (network? PATCHWORKPP_GIT=mirror)" >&2; exit 1; }
      fi
      # Its C++ core (cpp/) and licence at the pinned commit: nothing else is needed.
      git -C "${src}" checkout -q "${PATCHWORKPP_COMMIT}" -- cpp LICENSE ||
        { echo "build.sh: ${src} has no commit ${PATCHWORKPP_COMMIT}" >&2; exit 1; }
      extra+=("-DGF_PATCHWORKPP_DIR=${src}") ;;
    *) echo "usage: $0 [--patchworkpp]" >&2; exit 2 ;;
  esac
done
mkdir -p "${BUILD}" || { echo "build.sh: cannot create ${BUILD}: set GF_PEERS_DIR" >&2; exit 1; }
if ! cmake -S "${HERE}" -B "${BUILD}" -DCMAKE_BUILD_TYPE=Release "${extra[@]}" \
  >"${BUILD}/configure.log" 2>&1; then
  tail -n 20 "${BUILD}/configure.log" >&2
  echo "build.sh: configure failed (needs cmake, g++, libpcl-dev; Patchwork++: libeigen3-dev," \
    "a C++20 compiler): ${BUILD}/configure.log" >&2
  exit 1
fi
if ! cmake --build "${BUILD}" -j"${GF_JOBS:-2}" >"${BUILD}/build.log" 2>&1; then
  grep -m 20 -E "error|Error" "${BUILD}/build.log" >&2 || true
  echo "build.sh: build failed: ${BUILD}/build.log" >&2
  exit 1
fi
echo "${BUILD}"
