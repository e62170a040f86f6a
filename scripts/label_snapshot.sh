#!/usr/bin/env bash
# Writes the labels of every dev input under every method and preset, so that a change which must
# not change results (a refactor, a new SIMD path) can be checked byte for byte:
#   scripts/label_snapshot.sh OUT_DIR [EVAL_BINARY]      # write OUT_DIR/<case>/<stem>.gnd
#   scripts/label_snapshot.sh --compare DIR_A DIR_B       # count differing labels per case
# Cases: voxel, normal and voxel_paper with defaults; every config/*.yaml with its method;
# generated scenes (2 seeds each; garage, lidar16 and rosette reach the ceiling and sparse-line
# rules). Data: $GF_DATA_DIR, else data/ (scripts/get_data.sh), else ../shared/data; cases
# whose data is missing are skipped with a line saying so.
set -euo pipefail
# shellcheck source=scripts/common.sh
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"  # GF_ROOT, PATH with /usr/bin first
HERE="${GF_ROOT}"
DATA="$(gf_data_dir --or-repo)"

if [ "${1:-}" = "--compare" ]; then
  [ $# -eq 3 ] || { echo "usage: $0 --compare DIR_A DIR_B" >&2; exit 2; }
  exec python3 - "$2" "$3" <<'EOF'
import os, sys
a, b = sys.argv[1], sys.argv[2]
bad = 0
files = 0
for root, _, names in sorted(os.walk(a)):
    for n in sorted(x for x in names if x.endswith(".gnd")):
        pa = os.path.join(root, n)
        rel = os.path.relpath(pa, a)
        pb = os.path.join(b, rel)
        files += 1
        if not os.path.exists(pb):
            print(f"missing in {b}: {rel}"); bad += 1; continue
        x, y = open(pa, "rb").read(), open(pb, "rb").read()
        if len(x) != len(y):
            print(f"{rel}: {len(x)} vs {len(y)} labels"); bad += 1; continue
        d = sum(1 for i in range(len(x)) if x[i] != y[i]) if x != y else 0
        if d:
            print(f"{rel}: {d} of {len(x)} labels differ"); bad += 1
print(f"label_snapshot: {files} files compared, {bad} differ")
sys.exit(1 if bad or files == 0 else 0)
EOF
fi

OUT="${1:?usage: $0 OUT_DIR [EVAL_BINARY] | --compare DIR_A DIR_B}"
EVAL="${2:-${HERE}/.ws/devel/lib/ground_filter/ground_filter_eval}"
[ -x "${EVAL}" ] || { echo "no eval binary at ${EVAL} (build first or pass it)" >&2; exit 2; }
mkdir -p "${OUT}"
inputs=()
for d in semantickitti/seq00 offroad isprs airborne unlabelled; do
  if [ -d "${DATA}/${d}" ]; then inputs+=("${DATA}/${d}"); else echo "skip: no ${DATA}/${d}"; fi
done
scenes=()
for kind in lidar tls verge offroad trail airborne garage lidar16 rosette; do
  for seed in 1 2; do scenes+=("builtin:${kind}:${seed}"); done
done

run_case() {  # name, eval args...
  local name="$1"; shift
  mkdir -p "${OUT}/${name}"
  "${EVAL}" "$@" --write-labels "${OUT}/${name}" "${inputs[@]}" "${scenes[@]}" > "${OUT}/${name}.txt"
  echo "${name}: $(grep -m1 -i pooled "${OUT}/${name}.txt" || tail -1 "${OUT}/${name}.txt")"
}
run_case voxel --method voxel
run_case normal --method normal
run_case voxel_paper --method voxel_paper
for yaml in "${HERE}"/config/*.yaml; do
  stem="$(basename "${yaml}" .yaml)"
  method=voxel
  case "${stem}" in *_normal) method=normal ;; esac
  run_case "preset_${stem}" --method "${method}" --params "${yaml}"
done
