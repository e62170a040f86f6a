#!/usr/bin/env bash
# Builds the peer drivers this package carries (scripts/peers/CMakeLists.txt: PCL's SAC plane,
# from Debian's libpcl-dev) into ${GF_PEERS_DIR:-~/.cache/ground_filter_peers}/build, outside the
# package, where scripts/peers/run_peers.sh and scripts/speed_table.sh look for drivers. The
# other peers' drivers (Patchwork++, linefit, CSF) are built from their own code and put in the
# same folder (scripts/peers/README.md: the interface).
#   bash scripts/peers/build.sh        # prints the build folder
set -euo pipefail
export PATH="/usr/bin:/bin:${PATH}"
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
BUILD="${GF_PEERS_DIR:-${HOME}/.cache/ground_filter_peers}/build"
mkdir -p "${BUILD}" || { echo "build.sh: cannot create ${BUILD}: set GF_PEERS_DIR" >&2; exit 1; }
if ! cmake -S "${HERE}" -B "${BUILD}" -DCMAKE_BUILD_TYPE=Release >"${BUILD}/configure.log" 2>&1
then
  tail -n 20 "${BUILD}/configure.log" >&2
  echo "build.sh: configure failed (needs cmake, g++, libpcl-dev): ${BUILD}/configure.log" >&2
  exit 1
fi
if ! cmake --build "${BUILD}" -j"${GF_JOBS:-2}" >"${BUILD}/build.log" 2>&1; then
  grep -m 20 -E "error|Error" "${BUILD}/build.log" >&2 || true
  echo "build.sh: build failed: ${BUILD}/build.log" >&2
  exit 1
fi
echo "${BUILD}"
