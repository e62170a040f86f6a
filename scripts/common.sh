#!/usr/bin/env bash
# Shared by the README's commands: installs what is missing (apt, idempotent) and builds the
# package in an out-of-tree catkin workspace under .ws/ (git-ignored).
set -euo pipefail

# A pyenv python3 may shadow Debian's: catkin/genmsg need /usr/bin/python3 and its modules.
export PATH="/usr/bin:/bin:/usr/sbin:/sbin:${PATH}"

GF_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
GF_WS="${GF_WS:-${GF_ROOT}/.ws}"

# ---------------------------------------------------------------- packages per release
# Chosen from /etc/os-release (GF_OS_RELEASE names another file, for the tests). How each list
# was checked:
#   Debian 12 (bookworm): installed and run here (the development machine).
#   Debian 11 (bullseye): installed and run in a debootstrap root (scripts/check_platform.sh).
#   Debian 13 (trixie):   every name looked up with apt-cache against trixie's package index.
#   Ubuntu 22.04 (jammy): on paper (packages.ubuntu.com): its universe carries Debian's ROS 1
#                         packages under the same names; no libclang-rt-dev (see below).
#   Ubuntu 20.04 (focal), 24.04 (noble): on paper: their archives have no Debian ROS 1 packages
#                         (libnodeletlib-tools, libpcl-ros-dev: jammy only), so the scripts need
#                         an existing ROS there (Noetic on focal, ROS-O on noble; see gf_setup_ros).
# Sanitizer runtimes (scripts/sanitize.sh, scripts/fuzz.sh): in libclang-rt-dev where LLVM's
# defaults split it out (Debian 12/13, Ubuntu 24.04), else in libclang-common-N-dev, which clang
# itself depends on (Debian 11: clang 11, Ubuntu 20.04/22.04: clang 10/14).
# openjdk (11 of the ~1000 packages on a minimal root) comes from libpcl-dev -> libvtk9-dev
# (Depends: default-jdk); PCL's headers are needed, so it stays (docs/install.md).
gf_os_release() {
  local file="${GF_OS_RELEASE:-/etc/os-release}"
  GF_OS_ID="$(. "${file}" 2>/dev/null; echo "${ID:-unknown}")"
  GF_OS_VERSION="$(. "${file}" 2>/dev/null; echo "${VERSION_ID:-}")"
  GF_OS_NAME="$(. "${file}" 2>/dev/null; echo "${PRETTY_NAME:-${GF_OS_ID} ${GF_OS_VERSION}}")"
}
gf_os_release

# Non-ROS packages (compiler, CMake, libraries, test tools): apt-installed on every path.
GF_APT_SYSTEM_PACKAGES=(build-essential cmake git pkg-config python3 python3-nose python3-numpy
  libeigen3-dev libpcl-dev googletest libgtest-dev)
GF_APT_SYSTEM_TEST_PACKAGES=(xvfb xauth libgl1-mesa-dri imagemagick clang clang-format libomp-dev)
# Debian's ROS 1 packages (also in Ubuntu 22.04's universe): only where no ROS is installed.
GF_APT_ROS_PACKAGES=(
  catkin ros-core-dev rosbash python3-roslaunch python3-rostest librostest-dev
  python3-catkin-pkg python3-empy python3-rospkg
  libnodelet-dev libnodeletlib-tools libnodelet-topic-tools-dev pluginlib-dev
  libpcl-ros-dev libpcl-conversions-dev
  libdynamic-reconfigure-config-init-mutex-dev python3-dynamic-reconfigure
  libtf2-ros-dev python3-tf2-ros
  libdiagnostic-updater-dev librosbag-dev python3-rosbag
  python3-std-srvs python3-diagnostic-msgs
  libsensor-msgs-dev python3-sensor-msgs
)
# Tests and the rviz view only (GF_NO_TEST_DEPS=1 skips them). nanoflann: the optional
# reference of one kd-tree test.
GF_APT_ROS_TEST_PACKAGES=(rviz)
GF_APT_TEST_PACKAGES_OPTIONAL=(libnanoflann-dev)
GF_DEBIAN_ROS=1  # 0: the release's archive has no Debian ROS 1 packages
case "${GF_OS_ID}:${GF_OS_VERSION}" in
  debian:12 | debian:13 | ubuntu:24.04) GF_APT_SYSTEM_TEST_PACKAGES+=(libclang-rt-dev) ;;
  debian:11 | ubuntu:22.04) ;;
  ubuntu:20.04) GF_DEBIAN_ROS=0 ;;
  *) echo "[ground_filter] ${GF_OS_NAME} is not one of the releases these scripts know" \
       "(Debian 11/12/13, Ubuntu 20.04/22.04/24.04): trying Debian 12's package names" >&2
     GF_APT_SYSTEM_TEST_PACKAGES+=(libclang-rt-dev) ;;
esac
if [ "${GF_OS_ID}:${GF_OS_VERSION}" = ubuntu:24.04 ]; then GF_DEBIAN_ROS=0; fi

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
  # Loopback by name, or by address where even localhost does not resolve (no /etc/hosts).
  local lo=localhost
  gf_resolves localhost || lo=127.0.0.1
  if [ -z "${ROS_HOSTNAME:-}" ] && [ -z "${ROS_IP:-}" ]; then
    if [ "${lo}" = localhost ]; then export ROS_HOSTNAME=localhost; else export ROS_IP=127.0.0.1; fi
  fi
  local uri_host="${ROS_MASTER_URI:-}"
  uri_host="${uri_host#*://}"
  uri_host="${uri_host%%/*}"
  uri_host="${uri_host%:*}"
  if [ -z "${uri_host}" ] || ! gf_resolves "${uri_host}"; then
    if [ -n "${ROS_MASTER_URI:-}" ]; then
      echo "[ground_filter] ROS_MASTER_URI=${ROS_MASTER_URI} does not resolve: using ${lo}" >&2
    fi
    export ROS_MASTER_URI="http://${lo}:11311"
  fi
}

# The evaluation data folder, one rule for every script and tool (get_data.py, gf_data.py and
# src/tools/cli_args.cpp follow it too): $GF_DATA_DIR when set (an error when it is not a
# folder), else <repo>/data (scripts/get_data.sh fills it) when it exists, else
# <repo>/../shared/data when it exists; else an error saying to run scripts/get_data.sh.
#   DATA="$(gf_data_dir --required)"  # stops the caller (set -e) without data
#   DATA="$(gf_data_dir --optional)"  # empty without data (for steps that skip without it)
#   DATA="$(gf_data_dir --or-repo)"   # <repo>/data without data (tests then skip, naming it)
gf_data_dir() {
  local optional=0 root d
  [ "${1:-}" = --optional ] && optional=1
  [ "${1:-}" = --or-repo ] && optional=2
  if [ -n "${GF_DATA_DIR:-}" ]; then
    if [ -d "${GF_DATA_DIR}" ]; then
      (cd "${GF_DATA_DIR}" && pwd -P)
      return 0
    fi
    echo "[ground_filter] GF_DATA_DIR=${GF_DATA_DIR} is not a folder: fix or unset it" \
      "(bash scripts/get_data.sh --dest DIR fills a folder)" >&2
    return 1
  fi
  root="$(cd "${GF_ROOT}" && pwd -P)"
  for d in "${root}/data" "${root}/../shared/data"; do
    if [ -d "${d}" ]; then
      (cd "${d}" && pwd -P)
      return 0
    fi
  done
  [ "${optional}" = 1 ] && return 0
  [ "${optional}" = 2 ] && { echo "${GF_ROOT}/data"; return 0; }
  echo "[ground_filter] no data: run bash scripts/get_data.sh (fills ${root}/data)," \
    "or set GF_DATA_DIR to a copy" >&2
  return 1
}

gf_die() {
  echo "[ground_filter] ERROR: $*" >&2
  echo "[ground_filter] nothing was installed or changed." >&2
  exit 1
}

# Runs a command as root (sudo when needed); GF_DRY_RUN=1 prints it instead.
gf_root_run() {
  local sudo=""
  if [ "$(id -u)" != "0" ]; then sudo="sudo"; fi
  if [ "${GF_DRY_RUN:-0}" = "1" ]; then
    echo "[ground_filter] dry run, would run: ${sudo:+${sudo} }$*"
    return 0
  fi
  ${sudo} "$@"
}

gf_missing_apt() {  # prints the packages of "$@" that are not installed
  local p
  for p in "$@"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || echo "$p"
  done
}

# apt-get install of the missing packages among "$@". Without network (or an archive that lacks
# a name) it stops before installing anything and says what to do.
gf_apt_install() {
  local missing=() p
  while read -r p; do [ -n "$p" ] && missing+=("$p"); done < <(gf_missing_apt "$@")
  [ ${#missing[@]} -eq 0 ] && return 0
  echo "[ground_filter] installing with apt: ${missing[*]}"
  if ! command -v apt-get >/dev/null; then
    gf_die "apt-get not found: install these packages (or their equivalents) by hand: ${missing[*]}"
  fi
  export DEBIAN_FRONTEND=noninteractive
  if [ "${GF_DRY_RUN:-0}" != "1" ]; then
    local sudo=""
    if [ "$(id -u)" != "0" ]; then sudo="sudo"; fi
    if ! ${sudo} apt-get update -qq --error-on=any 2>/tmp/gf_apt_update.$$ &&
       ! { grep -q "error-on" /tmp/gf_apt_update.$$ && ${sudo} apt-get update -qq; }; then
      cat /tmp/gf_apt_update.$$ >&2; rm -f /tmp/gf_apt_update.$$
      gf_die "apt-get update failed (no network, or the archive is unreachable). Connect this" \
        "machine (or set an apt proxy/mirror) and run the command again, or install by hand:" \
        "${missing[*]}"
    fi
    rm -f /tmp/gf_apt_update.$$
    # A simulated install first: a name the archive lacks stops here, before any change.
    if ! apt-get install -s -qq --no-install-recommends "${missing[@]}" >/tmp/gf_apt_sim.$$ 2>&1; then
      cat /tmp/gf_apt_sim.$$ >&2; rm -f /tmp/gf_apt_sim.$$
      gf_die "apt cannot install: ${missing[*]} (${GF_OS_NAME}). See the message above;" \
        "docs/install.md lists the packages per release."
    fi
    rm -f /tmp/gf_apt_sim.$$
  fi
  gf_root_run apt-get install -y -qq --no-install-recommends "${missing[@]}"
}

# ---------------------------------------------------------------- an existing ROS comes first
GF_ROS2_DISTROS=" ardent bouncy crystal dashing eloquent foxy galactic humble iron jazzy kilted lyrical rolling "
GF_EXISTING_ROS=0
# When ROS_DISTRO is set or /opt/ros/*/setup.bash exists: use that ROS (sourcing its setup.bash
# when it is not sourced yet) and never apt-install Debian's ROS packages. GF_IGNORE_EXISTING_ROS=1
# goes the Debian-packages way regardless.
gf_setup_ros() {
  [ "${GF_IGNORE_EXISTING_ROS:-0}" = "1" ] && return 0
  local setups=() s d distro="${ROS_DISTRO:-}"
  for s in /opt/ros/*/setup.bash; do [ -f "$s" ] && setups+=("$s"); done
  if [ -z "${distro}" ] && [ ${#setups[@]} -eq 0 ]; then
    return 0
  fi
  if [ -n "${distro}" ]; then
    if [[ "${GF_ROS2_DISTROS}" == *" ${distro} "* ]] || [ "${ROS_VERSION:-1}" = "2" ]; then
      gf_die "ROS_DISTRO=${distro} is ROS 2; ground_filter is a ROS 1 (catkin, nodelet) package." \
        "Run the command in a shell where no ROS 2 is sourced: with a ROS 1 (source" \
        "/opt/ros/noetic/setup.bash first), or with no ROS at all to use Debian's ROS 1 packages" \
        "(unset ROS_DISTRO; GF_IGNORE_EXISTING_ROS=1 if /opt/ros holds only ROS 2)."
    fi
  else
    local ros1=()
    for s in "${setups[@]}"; do
      d="$(basename "$(dirname "$s")")"
      [[ "${GF_ROS2_DISTROS}" == *" ${d} "* ]] || ros1+=("$s")
    done
    if [ ${#ros1[@]} -eq 0 ]; then
      gf_die "only ROS 2 is installed (${setups[*]}); ground_filter needs ROS 1. Install ROS 1" \
        "(e.g. Noetic on Ubuntu 20.04), or run with GF_IGNORE_EXISTING_ROS=1 to use Debian's ROS 1" \
        "packages beside it."
    fi
    if [ ${#ros1[@]} -gt 1 ]; then
      gf_die "several ROS 1 installations: ${ros1[*]}. Source the one to use" \
        "(source /opt/ros/<distro>/setup.bash) and run the command again."
    fi
    distro="$(basename "$(dirname "${ros1[0]}")")"
  fi
  GF_EXISTING_ROS=1
  GF_ROS_PREFIX="/opt/ros/${distro}"
  if [ -z "${ROS_DISTRO:-}" ] || ! command -v catkin_make >/dev/null; then
    if [ ! -f "${GF_ROS_PREFIX}/setup.bash" ]; then
      gf_die "ROS_DISTRO=${distro} but ${GF_ROS_PREFIX}/setup.bash is missing and catkin_make is" \
        "not on PATH: this ROS looks half-installed. Reinstall its base (for Noetic:" \
        "sudo apt install --reinstall ros-noetic-ros-base) or source its setup.bash, then run again."
    fi
    set +u
    # shellcheck disable=SC1090
    if ! source "${GF_ROS_PREFIX}/setup.bash"; then
      set -u
      gf_die "sourcing ${GF_ROS_PREFIX}/setup.bash failed: this ROS looks half-installed." \
        "Reinstall its base (for Noetic: sudo apt install --reinstall ros-noetic-ros-base), then run again."
    fi
    set -u
  fi
  export ROS_DISTRO="${ROS_DISTRO:-${distro}}"
  local c missing=()
  for c in catkin_make roslaunch rosrun; do command -v "$c" >/dev/null || missing+=("$c"); done
  python3 -c "import catkin_pkg, rospkg" 2>/dev/null || missing+=("python3 modules catkin_pkg/rospkg")
  if [ ${#missing[@]} -gt 0 ]; then
    gf_die "the ROS at ${GF_ROS_PREFIX} (ROS_DISTRO=${ROS_DISTRO}) is incomplete: ${missing[*]}" \
      "not found. Install its base (for Noetic: sudo apt install ros-noetic-ros-base), or rosdep" \
      "install these, then run again."
  fi
  local where="${GF_ROS_PREFIX}"
  [ -d "${where}" ] || where="sourced in this shell"
  echo "[ground_filter] using the installed ROS ${ROS_DISTRO} (${where}); Debian's ROS" \
    "packages are not installed"
}

# With an existing ROS: the package.xml keys that are missing (scripts/ros_deps.py, offline),
# installed with rosdep; without rosdep, exactly which to install.
gf_install_deps_ros() {
  local roles="build,exec,test" missing
  if [ "${GF_NO_TEST_DEPS:-0}" = "1" ]; then roles="build,exec"; fi
  missing="$(python3 "${GF_ROOT}/scripts/ros_deps.py" --roles "${roles}" --missing)" ||
    gf_die "scripts/ros_deps.py failed"
  if [ -z "${missing}" ]; then
    echo "[ground_filter] every package.xml dependency is installed"
    return 0
  fi
  echo "[ground_filter] missing package.xml dependencies: $(echo ${missing})"
  if ! command -v rosdep >/dev/null; then
    gf_die "rosdep is not installed. Install these keys: $(echo ${missing})" \
      "- with rosdep: sudo apt install python3-rosdep; sudo rosdep init; rosdep update;" \
      "rosdep install --from-paths ${GF_ROOT} --ignore-src -y --rosdistro ${ROS_DISTRO};" \
      "or with apt: sudo apt install $(python3 "${GF_ROOT}/scripts/ros_deps.py" --roles "${roles}" \
      --missing --apt-names --distro "${ROS_DISTRO}" | tr '\n' ' ')"
  fi
  if [ "${GF_DRY_RUN:-0}" != "1" ] && ! rosdep resolve roscpp --rosdistro "${ROS_DISTRO}" >/dev/null 2>&1; then
    gf_die "rosdep has no rules yet (or no network): run 'sudo rosdep init; rosdep update'" \
      "online, then run again. Missing keys: $(echo ${missing})"
  fi
  local args=(--from-paths "${GF_ROOT}" --ignore-src -y --rosdistro "${ROS_DISTRO}")
  if [ "${GF_NO_TEST_DEPS:-0}" = "1" ]; then args+=(--dependency-types build --dependency-types exec \
    --dependency-types buildtool --dependency-types build_export); fi
  if [ "${GF_DRY_RUN:-0}" = "1" ]; then
    echo "[ground_filter] dry run, would run: rosdep install ${args[*]}"
    return 0
  fi
  rosdep install "${args[@]}" ||
    gf_die "rosdep install failed (no network?): connect and run again, or install: $(echo ${missing})"
}

gf_install_deps() {
  gf_setup_ros
  local system=("${GF_APT_SYSTEM_PACKAGES[@]}")
  if [ "${GF_NO_TEST_DEPS:-0}" != "1" ]; then system+=("${GF_APT_SYSTEM_TEST_PACKAGES[@]}"); fi
  if [ "${GF_EXISTING_ROS}" = "1" ]; then
    gf_install_deps_ros
    # Non-ROS tools of the scripts (compiler, CMake, test tools): apt, never a ROS package.
    gf_apt_install "${system[@]}"
    return 0
  fi
  if [ "${GF_DEBIAN_ROS}" = "0" ]; then
    gf_die "${GF_OS_NAME}'s archive has no Debian ROS 1 packages. Install ROS first (Ubuntu" \
      "20.04: ROS Noetic, http://wiki.ros.org/noetic/Installation/Ubuntu; Ubuntu 24.04: ROS-O)," \
      "source its setup.bash and run the command again: the scripts then use that ROS."
  fi
  local all=("${system[@]}" "${GF_APT_ROS_PACKAGES[@]}")
  if [ "${GF_NO_TEST_DEPS:-0}" != "1" ]; then
    all+=("${GF_APT_ROS_TEST_PACKAGES[@]}" "${GF_APT_TEST_PACKAGES_OPTIONAL[@]}")
  fi
  gf_apt_install "${all[@]}"
}

gf_build() {
  mkdir -p "${GF_WS}/src"
  # The workspace's package links back to the repository, so edits need no copy. Where the
  # workspace lies inside the repository (the default .ws/), one link to the whole repository
  # would be a loop (.ws/src/ground_filter/.ws/src/ground_filter/...) that rosrun's `find -L`
  # reports on every call ("File system loop detected"). There the package is a folder with one
  # link per top-level entry of the repository, less .git and the workspaces (.ws*); the links
  # are renewed by every build (an entry added at the top needs a gf_build, a catkin_make alone
  # does not see it). CMake finds the repository through package.xml's real path.
  local pkg="${GF_WS}/src/ground_filter" root_real ws_real top entry name
  root_real="$(cd "${GF_ROOT}" && pwd -P)"
  ws_real="$(cd "${GF_WS}" && pwd -P)"
  if [[ "${ws_real}/" == "${root_real}/"* ]]; then
    top="${ws_real#"${root_real}/"}"
    top="${top%%/*}"
    if [ -L "${pkg}" ]; then rm -f "${pkg}"; fi  # the former link to the whole repository
    mkdir -p "${pkg}"
    for entry in "${root_real}"/* "${root_real}"/.[!.]*; do
      [ -e "${entry}" ] || continue
      name="${entry##*/}"
      case "${name}" in .git | .ws* | .carry | .device | "${top}") continue ;; esac
      ln -sfn "${entry}" "${pkg}/${name}"
    done
    for entry in "${pkg}"/* "${pkg}"/.[!.]*; do  # links to entries since removed
      if [ -L "${entry}" ] && [ ! -e "${entry}" ]; then rm -f "${entry}"; fi
    done
  else
    ln -sfn "${GF_ROOT}" "${pkg}"
  fi
  cd "${GF_WS}"
  local jobs
  jobs="$(nproc 2>/dev/null || echo 2)"
  catkin_make -DCMAKE_BUILD_TYPE=Release -j"${jobs}" "$@"
  set +u
  # shellcheck disable=SC1091
  source "${GF_WS}/devel/setup.bash"
  set -u
  echo "[ground_filter] built. In your shell: source ${GF_WS}/devel/setup.bash; the tools:" \
    "rosrun ground_filter ground_filter_eval ... (or export" \
    "PATH=\"${GF_WS}/devel/lib/ground_filter:\$PATH\" to call them by name)"
}
