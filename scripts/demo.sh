#!/usr/bin/env bash
# The README's main command: installs what is missing, builds, and runs launch/demo.launch
# (generated LiDAR scene -> voxel ground filter nodelet) with demo_monitor printing one line per
# scan. It ends by itself after `scans` scans (default 30; with gui:=true when rviz is closed)
# and exits 0 only when scans were
# received. Arguments are roslaunch args, e.g.
#   bash scripts/demo.sh input:=data/semantickitti/seq00 scans:=12   (bash scripts/get_data.sh)
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"

# roslaunch runs nodes in ~/.ros: make a relative input path absolute while the caller's
# directory is still the current one.
args=()
scans=""
gui=false
name=ground_filter
for a in "$@"; do
  case "${a}" in
    input:=?*)
      path="${a#input:=}"
      if [[ "${path}" != /* && "${path}" != builtin:* && -e "${path}" ]]; then
        path="$(cd "$(dirname "${path}")" && pwd)/$(basename "${path}")"
      fi
      args+=("input:=${path}")
      ;;
    scans:=*) scans="${a#scans:=}" ;;
    gui:=*) gui="${a#gui:=}"; args+=("${a}") ;;
    name:=*) name="${a#name:=}"; args+=("${a}") ;;
    *) args+=("${a}") ;;
  esac
done

if [[ -z "${scans}" ]]; then
  # With rviz the demo streams until the window is closed (rviz is required by the launch).
  if [[ "${gui}" == true || "${gui}" == 1 ]]; then scans=0; else scans=30; fi
fi

gf_install_deps
gf_build
gf_ros_env  # loopback unless the caller's ROS_HOSTNAME / ROS_MASTER_URI resolve

# The monitor runs here, not as a required node of the launch: when it has printed its summary
# the launch is stopped cleanly (no "REQUIRED process has died"), and its status is ours.
roslaunch ground_filter demo.launch monitor:=false "${args[@]+"${args[@]}"}" &
launch_pid=$!
# The monitor's _max_scans:= goes to the master as the monitor starts: wait for roslaunch's master
# first, or roscpp prints "[setParam] Failed to contact master" in red while it retries.
for _ in $(seq 1 150); do
  rosparam get /rosdistro >/dev/null 2>&1 && break
  kill -0 "${launch_pid}" 2>/dev/null || break
  sleep 0.2
done
rosrun ground_filter demo_monitor ~ground:="/${name}/ground" \
  ~nonground:="/${name}/nonground" ~processing_time_ms:="/${name}/processing_time_ms" \
  _max_scans:="${scans}" &
monitor_pid=$!
stop() { kill -TERM "$@" 2>/dev/null || true; }
trap 'stop "${monitor_pid}"; stop "${launch_pid}"' INT TERM
status=1
while :; do
  if ! kill -0 "${monitor_pid}" 2>/dev/null; then
    set +e
    wait "${monitor_pid}"
    status=$?
    set -e
    break
  fi
  if ! kill -0 "${launch_pid}" 2>/dev/null; then
    echo "[demo] roslaunch ended before the monitor (see its output above)" >&2
    stop "${monitor_pid}"
    wait "${monitor_pid}" 2>/dev/null || true
    break
  fi
  sleep 0.2
done
stop "${launch_pid}"
wait "${launch_pid}" 2>/dev/null || true
echo "[demo] done (exit status ${status})"
exit "${status}"
