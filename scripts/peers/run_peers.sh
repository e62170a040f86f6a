#!/usr/bin/env bash
# Accuracy rows of the peer ground filters (Patchwork++, linefit, CSF, PCL's SAC plane, ...) in the
# format of scripts/eval_all.sh, scored by ground_filter_eval itself (--score-labels: the same
# loaders, ground-truth protocols and metrics as the package's own rows).
#   bash scripts/peers/run_peers.sh [GROUP...]        # groups: kitti offroad isprs airborne
#   bash scripts/peers/run_peers.sh heldout_kitti heldout_isprs heldout_airborne
#       # the held-out scans (bash scripts/get_data.sh --held-out)
#   PEERS="patchworkpp csf" bash scripts/peers/run_peers.sh kitti
# The peers are programs PEER_BIN/<peer>_driver (default ${GF_PEERS_DIR:-~/.cache/
# ground_filter_peers}/build), built by you from each peer's public code (scripts/peers/README.md
# gives the driver interface). Each is called once per group:
#   <peer>_driver --out DIR --repeats N FILE...
# and must write DIR/<stem>.gnd (one uint8 per input point, 1 ground, 0 otherwise) and print a
# line "RESULT <peer> <stem> ... median_ms=<ms> ..." per file. Timings (speed_table.sh takes the
# same drivers from PEER_BIN) are one-thread medians of REPEATS calls (default 3).
# Groups of a peer: PEER_GROUPS_<peer> (e.g. PEER_GROUPS_csf="kitti isprs"); default kitti and
# offroad (and heldout_kitti) for the sensor-centred methods (patchwork*, linefit*), every group for the others.
# Data: $GF_DATA_DIR, else data/ (bash scripts/get_data.sh), else ../shared/data.
# Exit status: 0 every row printed; 1 no driver, no data, no eval tool, or a driver failed (its
# row says so and the script goes on).
set -euo pipefail
export PATH="/usr/bin:/bin:${PATH}"
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
# shellcheck source=/dev/null
source "${ROOT}/scripts/common.sh"
DATA="$(gf_data_dir --required)"
EVAL="${GF_EVAL:-${ROOT}/.ws/devel/lib/ground_filter/ground_filter_eval}"
PEER_BIN="${PEER_BIN:-${GF_PEERS_DIR:-${HOME}/.cache/ground_filter_peers}/build}"
REPEATS="${REPEATS:-3}"
GROUPS_ASKED="${*:-kitti offroad isprs airborne}"
die() { echo "run_peers.sh: $*" >&2; exit 1; }
[ -x "${EVAL}" ] || die "${EVAL} not built: bash -c 'source scripts/common.sh; gf_build'"
PEERS="${PEERS:-}"
if [ -z "${PEERS}" ] && [ -d "${PEER_BIN}" ]; then
  PEERS="$(find "${PEER_BIN}" -maxdepth 1 -name '*_driver' -perm -u+x |
           sed 's|.*/||; s|_driver$||' | sort | tr '\n' ' ')"
fi
[ -n "${PEERS// /}" ] ||
  die "no <peer>_driver in ${PEER_BIN}: build the drivers (scripts/peers/README.md) or set PEER_BIN"

K="${DATA}/semantickitti/seq00"
group_files() {
  case "$1" in
    kitti) echo "${K}/000000.bin ${K}/000001.bin ${K}/000002.bin" ;;
    offroad) echo "${DATA}/offroad/rellis3d_00000_000001.pcd" ;;
    isprs) find -H "${DATA}/isprs" -maxdepth 1 -name '*.pcd' 2>/dev/null | sort | tr '\n' ' ' ;;
    airborne) find -H "${DATA}/airborne" -maxdepth 1 -name '*.pcd' 2>/dev/null | sort | tr '\n' ' ' ;;
    heldout_kitti) find -H "${DATA}/heldout/semantickitti" -maxdepth 1 -name '*.bin' 2>/dev/null |
                     sort | tr '\n' ' ' ;;
    heldout_isprs | heldout_airborne)
      local d="isprs"
      [ "$1" = heldout_airborne ] && d="airborne_pdal"
      find -H "${DATA}/heldout/${d}" -maxdepth 1 -name '*.pcd' 2>/dev/null | sort | tr '\n' ' ' ;;
    *) die "unknown group '$1' (kitti, offroad, isprs, airborne, heldout_kitti, heldout_isprs, heldout_airborne)" ;;
  esac
}
group_title() {
  case "$1" in
    kitti) echo "kitti seq00 0-2" ;;
    offroad) echo "offroad rellis3d" ;;
    isprs) echo "isprs 8 tiles" ;;
    airborne) echo "airborne 2 tiles" ;;
    heldout_kitti) echo "held-out kitti 2 frames" ;;
    heldout_isprs) echo "held-out isprs 7 tiles" ;;
    heldout_airborne) echo "held-out airborne_pdal 5 tiles" ;;
  esac
}

TMP="$(mktemp -d)"
trap 'rm -rf "${TMP}"' EXIT
: >"${TMP}/index.tsv"
failed=0
for g in ${GROUPS_ASKED}; do
  read -r -a files <<<"$(group_files "${g}")"
  for f in "${files[@]}"; do [ -r "${f}" ] || die "missing ${f}: run bash scripts/get_data.sh"; done
  [ "${#files[@]}" -gt 0 ] || die "no files for group ${g} in ${DATA}: run bash scripts/get_data.sh"
  for p in ${PEERS}; do
    var="PEER_GROUPS_${p//[^A-Za-z0-9_]/_}"  # linefit_h1.28: PEER_GROUPS_linefit_h1_28
    case "${p}" in
      patchwork* | linefit*) default="kitti offroad heldout_kitti" ;;  # a sensor at the origin
      *) default="kitti offroad isprs airborne heldout_kitti heldout_isprs heldout_airborne" ;;
    esac
    [[ " ${!var:-${default}} " == *" ${g} "* ]] || continue
    drv="${PEER_BIN}/${p}_driver"
    out="${TMP}/${g}/${p}"
    mkdir -p "${out}"
    row="${TMP}/${g}_${p}"
    if ! OMP_NUM_THREADS=1 "${drv}" --out "${out}" --repeats "${REPEATS}" "${files[@]}" \
          >"${row}.log" 2>&1; then
      echo "{\"error\": \"${drv} failed: see its output above\"}" >"${row}.json"
      echo "run_peers.sh: ${drv} failed on ${g}:" >&2
      tail -n 5 "${row}.log" >&2
      failed=1
    elif ! "${EVAL}" --json --score-labels "${out}" "${files[@]}" >"${row}.json" \
          2>"${row}.err"; then
      python3 -c 'import json,sys; print(json.dumps({"error": open(sys.argv[1]).read().strip()}))' \
        "${row}.err" >"${row}.json"
      failed=1
    fi
    printf '%s\t%s\t%s\t%s\n' "$(group_title "${g}")" "${p}" "${row}.json" "${row}.log" \
      >>"${TMP}/index.tsv"
  done
done

python3 - "${TMP}/index.tsv" "${REPEATS}" <<'PY'
import json, re, sys
print("peers scored by ground_filter_eval --score-labels; ms = sum over the files of the "
      "driver's median of %s one-thread calls" % sys.argv[2])
print("| group | method | files | P % | R % | F1 % | ms (sum) |")
print("|---" * 7 + "|")
f = lambda v: "-" if v is None else f"{100 * v:.2f}"
for line in open(sys.argv[1]):
    name, peer, path, log = line.rstrip("\n").split("\t")
    d = json.load(open(path))
    if "error" in d:
        print(f"| {name} | {peer} | error: {d['error']} | | | | |")
        continue
    ms = [float(m) for m in re.findall(r"median_ms=([0-9.]+)", open(log).read())]
    p = d["pooled"]
    total = f"{sum(ms):.0f}" if len(ms) == p["file_count"] else "-"
    print(f"| {name} | {peer} | {p['labelled_files']} | {f(p['precision'])} | "
          f"{f(p['recall'])} | {f(p['f1'])} | {total} |")
PY
exit "${failed}"
