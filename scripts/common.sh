#!/usr/bin/env bash
# Shared by the README's commands: installs what is missing (apt, idempotent) and builds the
# package in an out-of-tree catkin workspace under .ws/ (git-ignored).
set -euo pipefail

# A pyenv python3 may shadow Debian's: catkin/genmsg need /usr/bin/python3 and its modules.
export PATH="/usr/bin:/bin:/usr/sbin:/sbin:${PATH}"

GF_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
GF_WS="${GF_WS:-${GF_ROOT}/.ws}"

GF_APT_PACKAGES=(
  build-essential cmake git pkg-config python3
  catkin ros-core-dev rosbash python3-roslaunch python3-rostest librostest-dev
  python3-catkin-pkg python3-empy python3-nose python3-numpy
  libnodelet-dev libnodeletlib-tools libnodelet-topic-tools-dev pluginlib-dev
  libpcl-dev libpcl-ros-dev libpcl-conversions-dev
  libdynamic-reconfigure-config-init-mutex-dev python3-dynamic-reconfigure
  libtf2-ros-dev libtf2-sensor-msgs-dev python3-tf2-ros
  libdiagnostic-updater-dev librosbag-dev python3-rosbag
  python3-std-srvs python3-diagnostic-msgs
  libsensor-msgs-dev python3-sensor-msgs
  libeigen3-dev libnanoflann-dev googletest libgtest-dev
  clang libclang-rt-dev libomp-dev
  rviz xvfb xauth libgl1-mesa-dri imagemagick
)

gf_install_deps() {
  local missing=()
  for p in "${GF_APT_PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  if [ ${#missing[@]} -eq 0 ]; then
    return 0
  fi
  echo "[ground_filter] installing: ${missing[*]}"
  local sudo=""
  if [ "$(id -u)" != "0" ]; then sudo="sudo"; fi
  export DEBIAN_FRONTEND=noninteractive
  $sudo apt-get update -qq
  $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
}

gf_build() {
  mkdir -p "${GF_WS}/src"
  # The workspace links back to the repository, so edits need no copy.
  ln -sfn "${GF_ROOT}" "${GF_WS}/src/ground_filter"
  cd "${GF_WS}"
  local jobs
  jobs="$(nproc 2>/dev/null || echo 2)"
  catkin_make -DCMAKE_BUILD_TYPE=Release -j"${jobs}" "$@"
  set +u
  # shellcheck disable=SC1091
  source "${GF_WS}/devel/setup.bash"
  set -u
}
