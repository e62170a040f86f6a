#!/usr/bin/env bash
# Soak test of the nodelets (scripts/soak.py says what it does and what passes).
#   scripts/soak.sh [MINUTES] [--results DIR] [--rate HZ] [--scan PATH] [--malloc-trim-period S]
#                   [--malloc-mmap-threshold BYTES] [--malloc-trim-threshold BYTES]
#                   [--nodelets voxel,normal] [--simd LEVEL] [--robot-load] [--driver-in-manager]
#                   [--params FILE]
#                   [--set [voxel:|normal:]NAME=VALUE]...
# A robot's load, e.g. 30 minutes at 10 Hz, both nodelets, the AVX2 path, parameters fixed:
#   scripts/soak.sh 30 --rate 10 --simd avx2 --robot-load
# The same with the scan published inside the manager, as a driver's nodelet would (no
# serialisation of the clouds; scripts/soak.py says more):
#   scripts/soak.sh 30 --rate 10 --simd avx2 --robot-load --driver-in-manager
# Your configuration under that load (the YAML you pass to the launch file's params_file):
#   scripts/soak.sh 30 --rate 10 --robot-load --params my_params.yaml --set normal:threads=1
# Default 10 minutes at 20 Hz of unlabelled/os128_000000.pcd of the data folder ($GF_DATA_DIR,
# data/ of bash scripts/get_data.sh, ../shared/data). Needs the catkin
# build in .ws/ (scripts/run_tests.sh or gf_build). Starts its own roscore on a free port unless
# ROS_MASTER_URI is set; ROS_HOSTNAME defaults to loopback. Logs: .ws/soak_logs/.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
MINUTES=10
EXTRA=()
while [ $# -gt 0 ]; do
  case "$1" in
    --results|--rate|--scan|--malloc-trim-period|--malloc-mmap-threshold|--malloc-trim-threshold|\
    --nodelets|--simd|--params|--set)
      EXTRA+=("$1" "$2"); shift 2 ;;
    --robot-load|--driver-in-manager) EXTRA+=("$1"); shift ;;
    [0-9]*) MINUTES="$1"; shift ;;
    *) echo "usage: $0 [MINUTES] [--results DIR] [--rate HZ] [--scan PATH] [--malloc-trim-period S]" \
         "[--malloc-mmap-threshold BYTES] [--malloc-trim-threshold BYTES] [--nodelets voxel,normal]" \
         "[--simd LEVEL] [--robot-load] [--driver-in-manager] [--params FILE] [--set [voxel:|normal:]NAME=VALUE]..." \
         >&2; exit 2 ;;
  esac
done
set +u
# shellcheck disable=SC1091
source "${GF_WS}/devel/setup.bash"
set -u
export ROS_HOSTNAME="${ROS_HOSTNAME:-localhost}"
if [ -z "${ROS_MASTER_URI:-}" ]; then
  port="$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')"
  export ROS_MASTER_URI="http://localhost:${port}"
fi
export ROS_LOG_DIR="${GF_WS}/soak_logs/ros"
exec python3 "${GF_ROOT}/scripts/soak.py" run --minutes "${MINUTES}" "${EXTRA[@]}"
