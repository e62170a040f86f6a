#!/usr/bin/env bash
# Precision / recall / F1 per dev group for each method, one markdown table (README/docs
# "Accuracy"). Needs a build (bash -c 'source scripts/common.sh; gf_build').
#   bash scripts/eval_all.sh        # voxel, normal, normal + vehicle_lidar_normal preset,
#                                   # voxel_paper; every group
#   METHODS="voxel normal@vehicle_lidar_normal" bash scripts/eval_all.sh   # METHOD[@PRESET]
#   bash scripts/eval_all.sh --set plane_distance=0.2   # extra eval arguments for every run
#   HELDOUT=1 METHODS="voxel normal" bash scripts/eval_all.sh   # the held-out groups instead
#       (bash scripts/get_data.sh --held-out: data folder's heldout/)
#   SEEDS="0 1 2 3 4 5 6 7 8 9" METHODS=normal bash scripts/eval_all.sh   # normal rows once per
#       ransac_seed: P / R / F1 of the first seed, then the F1 mean, sd and min-max over the seeds
# Groups: SemanticKITTI seq00 0-2 (labelled), RELLIS-3D off-road frame, ISPRS 8 tiles and the two
# airborne tiles (defaults and the airborne preset: config/airborne.yaml for voxel,
# config/airborne_normal.yaml for normal; no preset row for voxel_paper), generated scenes
# (2 seeds per kind; the generated airborne tiles with the airborne presets).
# Pooled over the files of a group; ms = sum of the files' filter times.
set -euo pipefail
export PATH="/usr/bin:/bin:${PATH}"
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# (source=/dev/null: shellcheck would take a function's local array of common.sh for this file's)
# shellcheck source=/dev/null
source "${ROOT}/scripts/common.sh"
# Data folder: $GF_DATA_DIR, else data/ (scripts/get_data.sh), else ../shared/data; needed only
# for the default groups.
if [ -z "${GROUPS_DEF:-}" ]; then
  DATA="$(gf_data_dir --required)"
else
  DATA="$(gf_data_dir --optional)"
fi
EVAL="${GF_EVAL:-${ROOT}/.ws/devel/lib/ground_filter/ground_filter_eval}"
METHODS="${METHODS:-voxel normal normal@vehicle_lidar_normal voxel_paper}"
SEEDS="${SEEDS:-}"  # ransac_seed values for the normal method (the voxel methods have no seed)
[ -x "${EVAL}" ] || { echo "eval_all.sh: ${EVAL} not built" >&2; exit 1; }

K="${DATA}/semantickitti/seq00"
if [ "${HELDOUT:-0}" = 1 ] && [ -z "${GROUPS_DEF:-}" ]; then
  H="${DATA}/heldout"
  [ -d "${H}/isprs" ] || { echo "eval_all.sh: no ${H}: bash scripts/get_data.sh --held-out" >&2; exit 1; }
  GROUPS_DEF="held-out kitti (seq04 000056, spvnas 000000)||${H}/semantickitti
held-out isprs 7 tiles||${H}/isprs
held-out airborne_pdal 5 tiles||${H}/airborne_pdal"
fi
# name|extra eval arguments|paths
GROUPS_DEF="${GROUPS_DEF:-kitti seq00 0-2||${K}/000000.bin ${K}/000001.bin ${K}/000002.bin
offroad rellis3d||${DATA}/offroad
isprs 8 tiles||${DATA}/isprs
isprs 8 tiles, preset airborne|preset:airborne|${DATA}/isprs
airborne 2 tiles||${DATA}/airborne
airborne 2 tiles, preset airborne|preset:airborne|${DATA}/airborne
gen street (lidar:1,2)||builtin:lidar:1 builtin:lidar:2
gen 16-beam street (lidar16:1,2)||builtin:lidar16:1 builtin:lidar16:2
gen verge (verge:1,2)||builtin:verge:1 builtin:verge:2
gen offroad (offroad:1,2)||builtin:offroad:1 builtin:offroad:2
gen trail (trail:1,2)||builtin:trail:1 builtin:trail:2
gen airborne (airborne:1,2), preset airborne|preset:airborne|builtin:airborne:1 builtin:airborne:2
gen registered (mls, slam, stations, tls_far)||builtin:mls:1 builtin:slam:1 builtin:stations:1 builtin:tls_far:1
gen nadir (uav, corridor)||builtin:uav:1 builtin:corridor:1}"

TMP="$(mktemp -d)"
trap 'rm -rf "${TMP}"' EXIT
i=0
while IFS='|' read -r name extra paths; do
  [ -n "${name}" ] || continue
  for token in ${METHODS}; do
    # METHOD or METHOD@PRESET (= --params config/PRESET.yaml on every group).
    m="${token%%@*}"
    args=""
    [[ "${token}" == *@* ]] && args="--params ${ROOT}/config/${token#*@}.yaml"
    if [[ "${extra}" == preset:* ]]; then
      preset="${extra#preset:}"
      case "${token}" in
        voxel) args="--params ${ROOT}/config/${preset}.yaml" ;;
        normal) args="--params ${ROOT}/config/${preset}_normal.yaml" ;;
        *) continue ;;
      esac
    fi
    seeds="-"
    [ "${m}" = normal ] && [ -n "${SEEDS}" ] && seeds="${SEEDS}"
    for seed in ${seeds}; do
      i=$((i + 1))
      seed_arg=""
      [ "${seed}" != "-" ] && seed_arg="--set ransac_seed=${seed}"
      # shellcheck disable=SC2086
      if ! "${EVAL}" --json --method "${m}" ${args} "$@" ${seed_arg} ${paths} > "${TMP}/${i}.json" 2> "${TMP}/${i}.err"; then
        echo "{\"error\": $(python3 -c 'import json,sys; print(json.dumps(open(sys.argv[1]).read().strip()))' "${TMP}/${i}.err")}" > "${TMP}/${i}.json"
      fi
      printf '%s\t%s\t%s\n' "${name}" "${token}" "${TMP}/${i}.json" >> "${TMP}/index.tsv"
    done
  done
done <<< "${GROUPS_DEF}"

python3 - "${TMP}/index.tsv" "$*" "${SEEDS}" <<'PY'
import json, statistics, sys
rows = [l.rstrip("\n").split("\t") for l in open(sys.argv[1])]
extra, seeds = sys.argv[2], sys.argv[3].split()
print("eval arguments: " + (extra if extra else "(defaults)"))
spread = len(seeds) > 1
head = "| group | method | files | P % | R % | F1 % | ms (sum) |"
if spread:
    head += " F1 mean over %d seeds | sd | min-max |" % len(seeds)
print(head)
print("|---" * (10 if spread else 7) + "|")
runs = {}  # (group, method) -> pooled results, one per seed, in order
for name, method, path in rows:
    runs.setdefault((name, method), []).append(json.load(open(path)))
f = lambda v: "-" if v is None else f"{100 * v:.2f}"
for (name, method), ds in runs.items():
    d = ds[0]
    if "error" in d:
        print(f"| {name} | {method} | error: {d['error']} | | | | |")
        continue
    p = d["pooled"]
    line = (f"| {name} | {method} | {p['labelled_files']} | {f(p['precision'])} | "
            f"{f(p['recall'])} | {f(p['f1'])} | {p['ms']:.0f} |")
    f1s = [x["pooled"]["f1"] for x in ds if "error" not in x and x["pooled"]["f1"] is not None]
    if spread and len(ds) > 1 and len(f1s) == len(ds):
        line += (f" {100 * statistics.mean(f1s):.2f} | {100 * statistics.stdev(f1s):.2f} | "
                 f"{100 * min(f1s):.2f}-{100 * max(f1s):.2f} |")
    elif spread:
        line += " | | |"
    print(line)
PY
