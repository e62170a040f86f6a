#!/usr/bin/env bash
# The README's main command: installs what is missing, builds, and runs launch/demo.launch
# (generated LiDAR scene -> voxel ground filter nodelet -> per-scan report). It ends by itself
# after `scans` scans (default 30). Arguments are roslaunch args, e.g.
#   bash scripts/demo.sh input:=../shared/data/semantickitti/seq00 scans:=12
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"

# roslaunch runs nodes in ~/.ros: make a relative input path absolute while the caller's
# directory is still the current one.
args=()
for a in "$@"; do
  case "${a}" in
    input:=?*)
      path="${a#input:=}"
      if [[ "${path}" != /* && "${path}" != builtin:* && -e "${path}" ]]; then
        path="$(cd "$(dirname "${path}")" && pwd)/$(basename "${path}")"
      fi
      args+=("input:=${path}")
      ;;
    *) args+=("${a}") ;;
  esac
done

gf_install_deps
gf_build
exec roslaunch ground_filter demo.launch "${args[@]+"${args[@]}"}"
