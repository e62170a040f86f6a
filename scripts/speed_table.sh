#!/usr/bin/env bash
# Time per KITTI frame of both methods on every SIMD path this CPU runs, and of the peer drivers in
# PEER_BIN (scripts/peers/README.md; when present), alternating the tools in rounds; prints one
# markdown table with the CPU model, its SIMD levels and the load. Timings drift between minutes: read a table as a
# whole (the ratios), never one row against another run's.
#   bash scripts/speed_table.sh                 # 3 rounds, 15 timed calls per frame and tool
#   ROUNDS=5 REPEAT=21 bash scripts/speed_table.sh
#   PEERS="patchworkpp" bash scripts/speed_table.sh   # only these peers ("" = none)
#   EVERY_POINT=1 bash scripts/speed_table.sh   # + normal rows with a normal for every point
#                                               #   (sample_stride 1, k 64: the paper's way)
#   STRIDE3=1 bash scripts/speed_table.sh       # + normal rows with every third point sampled
#                                               #   (sample_stride 3, k 28: docs/normal_speed.md)
# Rows: voxel (1 thread), normal (1 and 2 threads) at each GF_SIMD level the CPU has, and the
# peers' drivers (one thread, their segmentation call only; CSF with REPEAT/2 calls).
# Needs a build (bash -c 'source scripts/common.sh; gf_build'); data: $GF_DATA_DIR, else data/
# (bash scripts/get_data.sh), else ../shared/data.
set -euo pipefail
# shellcheck source=scripts/common.sh
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"  # GF_ROOT, PATH with /usr/bin first
ROOT="${GF_ROOT}"
DATA="$(gf_data_dir --required)"
BIN="${GF_BIN:-${ROOT}/.ws/devel/lib/ground_filter}"
PEER_BIN="${PEER_BIN:-${GF_PEERS_DIR:-${HOME}/.cache/ground_filter_peers}/build}"
ROUNDS="${ROUNDS:-3}"
REPEAT="${REPEAT:-15}"
PEERS="${PEERS-patchworkpp linefit csf pcl_ransac pcl_ransac_native}"
K="${DATA}/semantickitti/seq00"
FILES=("${K}/000000.bin" "${K}/000001.bin" "${K}/000002.bin")
BENCH="${BIN}/ground_filter_benchmark"
[ -x "${BENCH}" ] || { echo "speed_table.sh: ${BENCH} not built" >&2; exit 1; }
for f in "${FILES[@]}"; do [ -r "$f" ] || { echo "speed_table.sh: missing $f" >&2; exit 1; }; done
TMP="$(mktemp -d)"
trap 'rm -rf "${TMP}"' EXIT

# SIMD levels this CPU runs (the benchmark prints "SIMD <level> (best <best>)").
best="$("${BENCH}" --repeat 1 --warmup 0 "${FILES[0]}" 2>&1 | sed -n 's/.*(best \([a-z0-9]*\)).*/\1/p' | head -1)"
case "${best}" in
  avx512) LEVELS="avx512 avx2 portable" ;;
  avx2) LEVELS="avx2 portable" ;;
  neon) LEVELS="neon portable" ;;
  *) LEVELS="portable" ;;
esac

# tool name | command prefix (files and output parsing follow)
TOOLS=("voxel|GF_SIMD=${best} ${BENCH} --method voxel --threads 1")
for lv in ${LEVELS}; do
  [ "${lv}" = portable ] && continue
  TOOLS+=("normal ${lv}, 1 thread|GF_SIMD=${lv} ${BENCH} --method normal --threads 1")
  TOOLS+=("normal ${lv}, 2 threads|GF_SIMD=${lv} ${BENCH} --method normal --threads 2")
  if [ "${EVERY_POINT:-0}" = 1 ]; then
    TOOLS+=("normal ${lv}, 2 threads, every point (sample_stride 1, k 64)|GF_SIMD=${lv} ${BENCH} --method normal --threads 2 --set sample_stride=1 --set k=64")
  fi
  if [ "${STRIDE3:-0}" = 1 ]; then
    TOOLS+=("normal ${lv}, 2 threads, sample_stride 3, k 28|GF_SIMD=${lv} ${BENCH} --method normal --threads 2 --set sample_stride=3 --set k=28")
  fi
done
for p in ${PEERS}; do
  drv="${PEER_BIN}/${p}_driver"
  if [ -x "${drv}" ]; then
    TOOLS+=("${p}|peer ${drv}")
  else
    echo "speed_table.sh: ${drv} not built: row ${p} left out (scripts/peers/README.md)" >&2
  fi
done

load_start="$(cut -d' ' -f1 /proc/loadavg)"
for r in $(seq 1 "${ROUNDS}"); do
  i=0
  for t in "${TOOLS[@]}"; do
    name="${t%%|*}"; cmd="${t#*|}"
    out="${TMP}/r${r}_t${i}.txt"
    if [ "${cmd#peer }" != "${cmd}" ]; then
      n="${REPEAT}"; [ "${name}" = csf ] && n=$(( (REPEAT + 1) / 2 ))
      mkdir -p "${TMP}/gnd"
      OMP_NUM_THREADS=1 ${cmd#peer } --out "${TMP}/gnd" --repeats "${n}" "${FILES[@]}" 2>&1 |
        sed -n 's/.*median_ms=\([0-9.]*\).*/\1/p' > "${out}"
    else
      env ${cmd} --repeat "${REPEAT}" "${FILES[@]}" 2>&1 |
        awk '$1 ~ /\.bin$/ && NF >= 6 {print $4}' > "${out}"
    fi
    i=$((i + 1))
  done
done
load_end="$(cut -d' ' -f1 /proc/loadavg)"

model="$(lscpu | sed -n 's/^Model name:[[:space:]]*//p' | head -1)"
flags="$(grep -m1 -o -w -E 'avx512f|avx2|fma|neon|asimd' /proc/cpuinfo | sort -u | tr '\n' ' ')"
echo "CPU: ${model:-unknown} (${flags:-no AVX2}); best SIMD path ${best}; $(nproc) cores;" \
  "load ${load_start} -> ${load_end}; ${ROUNDS} rounds x ${#FILES[@]} KITTI frames, ${REPEAT} calls each"
echo
echo "| tool | ms per KITTI frame: median (range) of per-frame medians | × Patchwork++ |"
echo "|---|---|---|"
python3 - "${TMP}" "${ROUNDS}" "${TOOLS[@]}" <<'EOF'
import statistics, sys
tmp, rounds, tools = sys.argv[1], int(sys.argv[2]), sys.argv[3:]
rows = []
for i, t in enumerate(tools):
    vals = []
    for r in range(1, rounds + 1):
        with open(f"{tmp}/r{r}_t{i}.txt") as f:
            vals += [float(x) for x in f.read().split()]
    rows.append((t.split("|")[0], vals))
ref = next((statistics.median(v) for n, v in rows if n == "patchworkpp" and v), None)
for name, v in rows:
    if not v:
        print(f"| {name} | no output | |")
        continue
    med = statistics.median(v)
    ratio = f"{med / ref:.2f}" if ref else ""
    print(f"| {name} | {med:.1f} ({min(v):.1f}–{max(v):.1f}) | {ratio} |")
EOF
