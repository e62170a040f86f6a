#!/usr/bin/env bash
# Shared by the README's commands: installs what is missing (apt, idempotent) and builds the
# package in an out-of-tree catkin workspace under .ws/ (git-ignored).
set -euo pipefail

# A pyenv python3 may shadow Debian's: catkin/genmsg need /usr/bin/python3 and its modules.
export PATH="/usr/bin:/bin:/usr/sbin:/sbin:${PATH}"

GF_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
GF_WS="${GF_WS:-${GF_ROOT}/.ws}"

# Debian 12 packages. openjdk (11 of the ~1000 packages on a minimal root) comes from libpcl-dev
# -> libvtk9-dev (Depends: default-jdk); PCL's headers are needed, so it stays (docs/install.md).
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
  libeigen3-dev googletest libgtest-dev
)
# Tests and the rviz view only (GF_NO_TEST_DEPS=1 skips them: 51 packages fewer on a minimal
# root). nanoflann: the optional reference of one kd-tree test.
GF_APT_TEST_PACKAGES=(libnanoflann-dev rviz xvfb xauth libgl1-mesa-dri imagemagick
  clang libclang-rt-dev libomp-dev)  # clang: sanitizer build and libFuzzer (scripts/sanitize.sh)
if [ "${GF_NO_TEST_DEPS:-0}" != "1" ]; then
  GF_APT_PACKAGES+=("${GF_APT_TEST_PACKAGES[@]}")
fi

# ROS on this machine only, also where the hostname does not resolve (containers): keeps the
# caller's ROS_HOSTNAME / ROS_IP / ROS_MASTER_URI when they resolve, else uses loopback.
# (Python: scripts/ros_launch_helpers.py loopback_env.)
gf_resolves() { getent ahosts "$1" >/dev/null 2>&1; }
gf_ros_env() {
  if [ -n "${ROS_HOSTNAME:-}" ] && ! gf_resolves "${ROS_HOSTNAME}"; then
    echo "[ground_filter] ROS_HOSTNAME=${ROS_HOSTNAME} does not resolve: using localhost" >&2
    unset ROS_HOSTNAME
  fi
  if [ -z "${ROS_HOSTNAME:-}" ] && [ -n "${ROS_IP:-}" ] && ! gf_resolves "${ROS_IP}"; then
    echo "[ground_filter] ROS_IP=${ROS_IP} is not an address: using localhost" >&2
    unset ROS_IP
  fi
  if [ -z "${ROS_HOSTNAME:-}" ] && [ -z "${ROS_IP:-}" ]; then
    export ROS_HOSTNAME=localhost
  fi
  local uri_host="${ROS_MASTER_URI:-}"
  uri_host="${uri_host#*://}"
  uri_host="${uri_host%%/*}"
  uri_host="${uri_host%:*}"
  if [ -z "${uri_host}" ] || ! gf_resolves "${uri_host}"; then
    if [ -n "${ROS_MASTER_URI:-}" ]; then
      echo "[ground_filter] ROS_MASTER_URI=${ROS_MASTER_URI} does not resolve: using localhost" >&2
    fi
    export ROS_MASTER_URI=http://localhost:11311
  fi
}

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
