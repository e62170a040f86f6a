#!/usr/bin/env bash
# "An existing ROS comes first", checked with a stand-in: run by scripts/check_platform.sh inside
# its Debian root (as root, without network), where Debian's ROS 1 is installed in /usr. A fake
# /opt/ros/noetic/setup.bash (ROS_DISTRO=noetic, Debian's ROS from /usr) plays an installed
# Noetic. Checks, each printed as CHECK <name> <passed|failed> <detail>:
#   dry_run        scripts/common.sh uses that ROS and would install no ROS package with apt;
#   demo           `bash scripts/demo.sh` with a ROS already sourced (ROS_DISTRO=Debian, Debian's
#                  ROS as it names itself) builds and runs offline (apt never needed);
#   missing_dep    a dependency missing, no rosdep: stops, names the key and the package to
#                  install, changes nothing;
#   ros2_distro    ROS_DISTRO=humble: stops with what to do, changes nothing;
#   half_installed /opt/ros/noetic without setup.bash: stops with what to do, changes nothing;
#   no_network     no ROS, a package to apt-install and no network: stops, changes nothing.
# Exit status 0 only when every check passed. Leaves the root as it found it.
set -uo pipefail
REPO="${1:-$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)}"
cd "${REPO}"
FAKE=/opt/ros/noetic
LOG="$(mktemp -d /tmp/gf_existing_ros_XXXXXX)"
fails=0
check() {  # check <name> <passed|failed> <detail>
  echo "CHECK $1 $2 $3"
  [ "$2" = passed ] || fails=$((fails + 1))
}
# failed_with_log <name> <log name> <lines>: the case failed; its exit status (rc) and the last
# lines of ${LOG}/<log name>.log.
failed_with_log() { check "$1" failed "rc ${rc}: $(tail -n "$3" "${LOG}/$2.log" | tr '\n' ' ')"; }
# expect_stop <name> <log name> <reason regex>: passed when the command failed (rc), its log
# gives the reason and says nothing was changed, and the package state is as before.
expect_stop() {
  local log="${LOG}/$2.log"
  if [ "${rc}" != 0 ] && grep -q -- "$3" "${log}" &&
     grep -q "nothing was installed or changed" "${log}" && [ "$(state)" = "${before}" ]; then
    check "$1" passed "stops: $(grep -m1 -o -- "$3" "${log}")"
  else
    failed_with_log "$1" "$2" 5
  fi
}
state() { md5sum /var/lib/dpkg/status | cut -d' ' -f1; ls -la /opt/ros 2>/dev/null | md5sum | cut -d' ' -f1; }
had_opt_ros=0
[ -e /opt/ros ] && had_opt_ros=1
hidden=""
restore() {
  [ -n "${hidden}" ] && [ -e "${hidden}.gf_hidden" ] && mv "${hidden}.gf_hidden" "${hidden}"
  [ -e "${FAKE}/setup.bash.gf_hidden" ] && mv "${FAKE}/setup.bash.gf_hidden" "${FAKE}/setup.bash"
  rm -rf "${FAKE}"
  [ "${had_opt_ros}" = 1 ] || rm -rf /opt/ros
}
trap restore EXIT
[ -e "${FAKE}" ] && { echo "CHECK setup failed ${FAKE} exists already"; exit 1; }

mkdir -p "${FAKE}"
cat >"${FAKE}/setup.bash" <<'EOF'
# Stand-in for an installed ROS Noetic: Debian's ROS 1 packages in /usr.
export ROS_DISTRO=noetic ROS_VERSION=1 ROS_PYTHON_VERSION=3
export ROS_ROOT=/usr/share/ros ROS_ETC_DIR=/usr/etc/ros
export ROS_PACKAGE_PATH=/usr/share
# (No CMAKE_PREFIX_PATH entry: /usr is CMake's default prefix, and catkin rejects a prefix that
# is not a catkin install space.)
export GF_STANDIN_SOURCED=1
EOF
mkdir -p "${FAKE}/share"

# 1. Dry run: which install commands would run.
before="$(state)"
GF_DRY_RUN=1 bash -c 'source scripts/common.sh; gf_install_deps' >"${LOG}/dry.log" 2>&1
rc=$?
ros_apt="$(grep "would run: .*apt-get install" "${LOG}/dry.log" | tr ' ' '\n' |
  grep -E '^(catkin|ros-|rosbash|python3-ros|python3-catkin|librosbag|libnodelet|libpcl-ros|libtf2|rviz|python3-tf2|libdiagnostic|librostest|python3-dynamic|python3-std-srvs|python3-diagnostic|python3-sensor|libsensor-msgs)' || true)"
if [ "${rc}" = 0 ] && grep -q "using the installed ROS noetic (/opt/ros/noetic)" "${LOG}/dry.log" &&
   grep -q "every package.xml dependency is installed" "${LOG}/dry.log" && [ -z "${ros_apt}" ] &&
   [ "$(state)" = "${before}" ]; then
  check dry_run passed "uses /opt/ros/noetic, no ROS package for apt; $(grep -c 'would run' "${LOG}/dry.log") install command(s) recorded"
else
  check dry_run failed "rc ${rc}, ROS packages for apt: '${ros_apt}': $(tail -n 5 "${LOG}/dry.log" | tr '\n' ' ')"
fi

# 2. The README's main command with a ROS already sourced in the shell, offline: builds and runs
# without apt. Debian's ROS names itself ROS_DISTRO=Debian (its catkin env hook complains about
# any other name), so this stand-in is that ROS as sourced, not the /opt/ros/noetic one.
ROS_DISTRO=Debian timeout 900 bash scripts/demo.sh scans:=5 >"${LOG}/demo.log" 2>&1
rc=$?
if [ "${rc}" = 0 ] && grep -q "using the installed ROS Debian" "${LOG}/demo.log" &&
   ! grep -q "installing with apt" "${LOG}/demo.log" && [ "$(state)" = "${before}" ]; then
  check demo passed "demo.sh with ROS_DISTRO=Debian sourced, offline: $(grep -m1 -E '^\[demo\] done' "${LOG}/demo.log")"
else
  failed_with_log demo demo 8
fi

# 3. A missing dependency, no rosdep: the key and the package to install, nothing changed.
hidden=/usr/share/diagnostic_updater/package.xml
mv "${hidden}" "${hidden}.gf_hidden"
before="$(state)"
bash -c 'source scripts/common.sh; gf_install_deps' >"${LOG}/missing.log" 2>&1
rc=$?
mv "${hidden}.gf_hidden" "${hidden}"
if [ "${rc}" != 0 ] && grep -q "rosdep is not installed" "${LOG}/missing.log" &&
   grep -q "diagnostic_updater" "${LOG}/missing.log" &&
   grep -q "ros-noetic-diagnostic-updater" "${LOG}/missing.log" && [ "$(state)" = "${before}" ]; then
  check missing_dep passed "stops: $(grep -m1 -o 'Install these keys: [^-]*' "${LOG}/missing.log")"
else
  failed_with_log missing_dep missing 5
fi

# 4. ROS_DISTRO names a ROS 2 distro.
ROS_DISTRO=humble bash scripts/demo.sh >"${LOG}/ros2.log" 2>&1
rc=$?
expect_stop ros2_distro ros2 'ROS_DISTRO=humble is ROS 2[^.]*'

# 5. Half-installed: ROS_DISTRO=noetic, /opt/ros/noetic without setup.bash, catkin_make hidden.
mv "${FAKE}/setup.bash" "${FAKE}/setup.bash.gf_hidden"
before="$(state)"
# (PATH emptied after common.sh is read: Debian's catkin_make in /usr/bin must not be found.)
ROS_DISTRO=noetic bash -c \
  'source scripts/common.sh; PATH=/nonexistent; gf_install_deps' >"${LOG}/half.log" 2>&1
rc=$?
mv "${FAKE}/setup.bash.gf_hidden" "${FAKE}/setup.bash"
if [ "${rc}" != 0 ] && grep -q "half-installed" "${LOG}/half.log" && [ "$(state)" = "${before}" ]; then
  check half_installed passed "stops: $(grep -m1 -o 'ROS_DISTRO=noetic but [^:]*' "${LOG}/half.log")"
else
  failed_with_log half_installed half 5
fi

# 6. No ROS, no network, something to apt-install: stops before any change.
rm -rf "${FAKE}"
[ "${had_opt_ros}" = 1 ] || rm -rf /opt/ros
before="$(state)"
bash -c \
  'source scripts/common.sh; GF_APT_SYSTEM_PACKAGES+=(hello); gf_install_deps' >"${LOG}/offline.log" 2>&1
rc=$?
expect_stop no_network offline 'apt-get update failed ([^)]*)'

echo "[existing_ros] logs in ${LOG}; $((6 - fails)) passed, ${fails} failed"
[ "${fails}" = 0 ]
