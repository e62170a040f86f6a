#!/usr/bin/env bash
# Run by scripts/ci_checks.sh inside `unshare --uts` after `hostname <fake>`: a container whose
# hostname does not resolve, with ROS_HOSTNAME set to an unresolvable name by "the user".
# Prints CHECK <name> <passed|failed> <detail> lines; always exits 0 (the lines are the result).
set -uo pipefail
GF_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
export PATH="/usr/bin:/bin:/usr/sbin:/sbin:${PATH}"
set +u
# shellcheck disable=SC1091
source "${GF_WS:-${GF_ROOT}/.ws}/devel/setup.bash"
set -u
export ROS_HOSTNAME=gf-unresolvable.invalid
unset ROS_IP ROS_MASTER_URI
ROS_HOME="$(mktemp -d /tmp/gf_container_check_XXXXXX)"
export ROS_HOME
log="${ROS_HOME}/out.log"
report() { echo "CHECK $1 $2 $3"; }

# Control: plain roslaunch with that environment fails (else this check would prove nothing).
port=$((20000 + RANDOM % 20000))
ROS_MASTER_URI="http://localhost:${port}" timeout 40 roslaunch -p "${port}" ground_filter \
  demo.launch scans:=2 >"${log}" 2>&1
if grep -q -E "Unable to contact my own server|cannot resolve host address" "${log}"; then
  report control passed "plain roslaunch fails here: $(grep -o -m1 -E 'Unable to contact my own server|cannot resolve host address' "${log}")"
else
  report control failed "plain roslaunch did not fail as expected: $(tail -n 3 "${log}" | tr '\n' ' ')"
fi

# scripts/demo.sh (scripts/common.sh gf_ros_env): overrides the unresolvable ROS_HOSTNAME.
timeout 180 bash "${GF_ROOT}/scripts/demo.sh" scans:=3 rate:=5 >"${log}" 2>&1
rc=$?
if [ "${rc}" = "0" ] && grep -q "\[demo_monitor\] summary: 3 scans" "${log}" \
   && grep -q "ROS_HOSTNAME=gf-unresolvable.invalid does not resolve" "${log}" \
   && ! grep -q "REQUIRED process" "${log}"; then
  report demo_sh passed "demo.sh: 3 scans, exit 0, clean end, ROS_HOSTNAME overridden"
else
  report demo_sh failed "demo.sh exit ${rc}: $(tail -n 5 "${log}" | tr '\n' ' ')"
fi

# scripts/ros_launch_helpers.py (rviz_screenshot.py, test_install_space.py, bag_playback_test.py).
timeout 180 python3 - "${GF_ROOT}/scripts" >"${log}" 2>&1 <<'PY'
import sys, time
sys.path.insert(0, sys.argv[1])
import ros_launch_helpers as h
p = h.roslaunch(["ground_filter", "demo.launch", "scans:=3", "rate:=5"], port=h.free_port())
deadline = time.monotonic() + 120
while p.running() and time.monotonic() < deadline:
    time.sleep(0.2)
ended_alone = not p.running()
rc = p.stop()
if not ended_alone:
    rc = 1  # it had to be stopped
print(p.output())
print("HELPER_RC=%d" % rc)
PY
if grep -q "\[demo_monitor\] summary: 3 scans" "${log}" \
   && grep -q "ROS_HOSTNAME=gf-unresolvable.invalid does not resolve" "${log}" \
   && grep -q "HELPER_RC=0" "${log}" && ! grep -q "REQUIRED process" "${log}"; then
  report python_helpers passed "ros_launch_helpers.roslaunch: demo.launch ran 3 scans and ended by itself (exit 0, no REQUIRED message), ROS_HOSTNAME overridden"
else
  report python_helpers failed "$(tail -n 5 "${log}" | tr '\n' ' ')"
fi
rm -rf "${ROS_HOME}"
exit 0
