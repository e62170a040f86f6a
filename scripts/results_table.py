#!/usr/bin/env python3
"""The README's results table, measured on this machine: one command for every figure of it.

Runs, in this order, each step's own table saved in OUT (default results_<date>/):

  eval.md       METHODS="voxel normal" bash scripts/eval_all.sh            (F1, both methods)
  heldout.md    HELDOUT=1 METHODS="voxel normal" bash scripts/eval_all.sh  (when <data>/heldout)
  peers.md      bash scripts/peers/run_peers.sh kitti offroad isprs airborne [heldout_kitti
                heldout_isprs]                                             (the peers' F1)
  sweep.md      python3 scripts/sensor_sweep.py --methods normal,voxel --peers ... --height-peers
                linefit                                                    (the 8-sensor column)
  speed.md      bash scripts/speed_table.sh                                (ms per KITTI frame)

then prints the README's table from them, headed by this machine's CPU model, cores, SIMD paths
and the date. The peers are the drivers built by `bash scripts/peers/build.sh --all` (PEER_BIN);
a peer not built leaves its cells empty ("–"). The GPU column needs an NVIDIA GPU:
`bash cuda/run_gpu_checks.sh` (docs/gpu.md).

  python3 scripts/results_table.py                  # every step (about 10 minutes on 2 cores)
  python3 scripts/results_table.py --skip sweep,speed   # the F1 columns only (a few minutes)
  python3 scripts/results_table.py --from DIR       # the table again from a run's saved steps

Needs a build and the data (scripts/get_data.sh, and --held-out for that column); the
environment of the steps applies (GF_DATA_DIR, GF_EVAL, GF_BIN, PEER_BIN, ROUNDS, REPEAT, ...).
"""
import argparse
import datetime
import os
import re
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
STEPS = ("eval", "heldout", "peers", "sweep", "speed")
PEER_DRIVERS = ("patchworkpp", "linefit", "linefit_h1.28", "csf", "pcl_ransac",
                "pcl_ransac_native")

# The README's rows: label, the name of the row in eval/run_peers tables per group (KITTI,
# RELLIS, ISPRS, ALS, held-out KITTI, held-out ISPRS), the sweep column, the speed rows.
ROWS = [
    ("**voxel** (defaults: `scan_type: auto`)", ["voxel"] * 6, "voxel", "voxel"),
    ("normal-vector (defaults: `scan_type: auto`)", ["normal"] * 6, "normal", "normal %s, 1 thread"),
    ("normal-vector, 2 threads", [None] * 6, None, "normal %s, 2 threads"),
    ("Patchwork++ (its default KITTI parameters)",
     ["patchworkpp", "patchworkpp", None, None, "patchworkpp", None], "patchworkpp", "patchworkpp"),
    ("linefit (its parameters; sensor height 1.8 m, RELLIS 1.28 m)",
     ["linefit", "linefit_h1.28", None, None, "linefit", None], "linefit", "linefit"),
    ("CSF (its defaults = PDAL `filters.csf`)", ["csf"] * 6, "csf", "csf"),
    ("PCL `SACSegmentation` plane, RANSAC 0.2 m", ["pcl_ransac"] * 6, "pcl_ransac", "pcl_ransac"),
]
GROUPS = ("kitti", "offroad", "isprs", "airborne", "held-out kitti", "held-out isprs")


def peer_bin():
    """The peers' drivers folder, as scripts/peers/run_peers.sh finds it."""
    return os.environ.get("PEER_BIN") or os.path.join(
        os.environ.get("GF_PEERS_DIR") or os.path.join(os.path.expanduser("~"), ".cache",
                                                      "ground_filter_peers"), "build")


def data_dir():
    """The data folder, as every tool finds it (scripts/gf_data.py)."""
    sys.path.insert(0, os.path.join(ROOT, "scripts"))
    from gf_data import data_dir as find  # noqa: E402
    return find()


def built_peers():
    """The drivers of the README's peer rows that are built."""
    b = peer_bin()
    return [p for p in PEER_DRIVERS if os.access(os.path.join(b, p + "_driver"), os.X_OK)]


def commands(data):
    """Each step's command (argv, extra environment), or None where it cannot run."""
    peers = built_peers()
    heldout = os.path.isdir(os.path.join(data, "heldout", "semantickitti")) if data else False
    eval_all = ["bash", os.path.join(ROOT, "scripts", "eval_all.sh")]
    sweep_peers = [p for p in peers if p in ("patchworkpp", "linefit", "csf", "pcl_ransac")]
    sweep = [sys.executable, os.path.join(ROOT, "scripts", "sensor_sweep.py"),
             "--methods", "normal,voxel"]
    if sweep_peers:
        sweep += ["--peers", ",".join(sweep_peers)]
        if "linefit" in sweep_peers:
            sweep += ["--height-peers", "linefit"]
    groups = ["kitti", "offroad", "isprs", "airborne"] + (
        ["heldout_kitti", "heldout_isprs"] if heldout else [])
    return {
        "eval": (eval_all, {"METHODS": "voxel normal"}),
        "heldout": (eval_all, {"METHODS": "voxel normal", "HELDOUT": "1"}) if heldout else None,
        "peers": ((["bash", os.path.join(ROOT, "scripts", "peers", "run_peers.sh")] + groups,
                   # F1 only: one timed call a file unless REPEATS says otherwise
                   {"PEERS": " ".join(peers), "REPEATS": os.environ.get("REPEATS", "1")})
                  if peers else None),
        "sweep": (sweep, {}),
        "speed": (["bash", os.path.join(ROOT, "scripts", "speed_table.sh")],
                  {"PEERS": " ".join(p for p in peers if p != "linefit_h1.28")}),
    }


def shown(argv, env):
    """The command as a user would type it from the repository root."""
    rel = [os.path.relpath(a, ROOT) if os.path.isabs(a) and a.startswith(ROOT) else a
           for a in argv]
    if rel and rel[0] == sys.executable:
        rel[0] = "python3"
    return " ".join(["%s=\"%s\"" % kv for kv in sorted(env.items())] + rel)


def table_rows(text):
    """The cells of every markdown row of `text` that is not a header or rule."""
    rows = []
    for line in text.splitlines():
        if not line.startswith("|") or set(line.replace("|", "").strip()) <= set("-: "):
            continue
        rows.append([c.strip() for c in line.strip().strip("|").split("|")])
    return rows


def f1_cells(texts):
    """{(group, method): F1 text} from eval_all.sh / run_peers.sh tables (F1 is column 6)."""
    out = {}
    for text in texts:
        for r in table_rows(text):
            if len(r) < 7 or r[0] == "group" or "preset" in r[0]:
                continue
            g = next((g for g in sorted(GROUPS, key=len, reverse=True) if r[0].startswith(g)),
                     None)
            if g and (g, r[1]) not in out:
                out[(g, r[1])] = r[5]
    return out


def sweep_means(text):
    """{column: mean F1 over all placements} from sensor_sweep.py's table."""
    head = next((r for r in table_rows(text) if r and r[0] == "sensor"), None)
    mean = next((r for r in table_rows(text) if r and r[0].endswith("placements: mean")), None)
    if not head or not mean:
        return {}
    return dict(zip(head[2:], mean[2:]))


def speed_cells(text):
    """({tool: 'median (range)'}, best SIMD path, CPU line) from speed_table.sh's output."""
    cells = {r[0]: r[1] for r in table_rows(text) if len(r) >= 2 and r[0] != "tool"}
    m = re.search(r"best SIMD path (\w+)", text)
    cpu = next((l for l in text.splitlines() if l.startswith("CPU:")), "")
    return cells, (m.group(1) if m else ""), cpu


def compose(out_dir):
    """The README's table from the steps saved in out_dir."""
    def read(step):
        p = os.path.join(out_dir, step + ".md")
        return open(p).read() if os.path.exists(p) else ""

    f1 = f1_cells([read("eval"), read("heldout"), read("peers")])
    sweep = sweep_means(read("sweep"))
    speed, best, cpu = speed_cells(read("speed"))
    lines = ["| method (parameters) | KITTI | RELLIS | ISPRS | ALS | held-out KITTI / ISPRS | "
             "8 sensors | ms, AVX-512 | ms, AVX2 |", "|---|---|---|---|---|---|---|---|---|"]
    na, missing = "–", "not run"  # not applicable (a sensor-centred peer on airborne tiles)
    # The voxel method and the peers have one time: in the column of the CPU's best path.
    best_col = 0 if best == "avx512" else 1
    for label, names, sweep_col, speed_row in ROWS:
        cells = [f1.get((g, n), missing) if n else na for g, n in zip(GROUPS, names)]
        if not any(names):
            cells = ["(same labels)"] + [""] * 5
        held = ("%s / %s" % (cells[4], cells[5])) if any(names) else ""
        s = sweep.get(sweep_col, missing) if sweep_col else ""
        if sweep_col == "linefit" and "linefit, true height" in sweep:
            s += "; %s at the true height" % sweep["linefit, true height"]
        ms = ["", ""]
        if speed_row and "%s" in speed_row:
            ms = [speed.get(speed_row % path, missing) for path in ("avx512", "avx2")]
        elif speed_row:
            ms[best_col] = speed.get(speed_row, missing)
        if speed_row == "pcl_ransac" and "pcl_ransac_native" in speed:
            ms[best_col] += "; `-march=native`: %s" % speed["pcl_ransac_native"]
        lines.append("| %s |" % " | ".join([label] + cells[:4] + [held, s] + ms))
    return cpu, "\n".join(lines)


def machine():
    """lscpu's model name, the cores and the SIMD extensions the CPU reports."""
    model, flags = "", ""
    try:
        with open("/proc/cpuinfo") as f:
            have = set(re.findall(r"\b(avx512f|avx2|fma|asimd)\b", f.read()))
        flags = " ".join(sorted(have)) or "no AVX2"
    except OSError:
        pass
    try:
        out = subprocess.run(["lscpu"], stdout=subprocess.PIPE, universal_newlines=True).stdout
        model = next((l.split(":", 1)[1].strip() for l in out.splitlines()
                      if l.startswith("Model name:")), "")
    except OSError:
        pass
    return "%s (%s), %d cores" % (model or "unknown CPU", flags, os.cpu_count() or 0)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", help="folder for the steps' tables (default results_<date>)")
    ap.add_argument("--skip", default="", metavar="STEP,...",
                    help="steps to leave out, of " + ", ".join(STEPS))
    ap.add_argument("--from", dest="src", metavar="DIR",
                    help="print the table from a run's saved steps; run nothing")
    args = ap.parse_args()
    skip = [s for s in args.skip.split(",") if s]
    bad = [s for s in skip if s not in STEPS]
    if bad:
        sys.exit("results_table.py: unknown step %s (%s)" % (", ".join(bad), ", ".join(STEPS)))
    if args.src:
        if not os.path.isdir(args.src):
            sys.exit("results_table.py: no folder %s" % args.src)
        out_dir = args.src
    else:
        out_dir = args.out or os.path.join(
            os.getcwd(), "results_" + datetime.datetime.now().strftime("%Y%m%d_%H%M%S"))
        os.makedirs(out_dir, exist_ok=True)
        try:
            data = data_dir()
        except Exception as e:  # gf_data.NoDataError: says what to do
            sys.exit("results_table.py: %s" % e)
        cmds = commands(data)
        with open(os.path.join(out_dir, "commands.txt"), "w") as log:
            for step in STEPS:
                if step in skip or cmds[step] is None:
                    why = "skipped" if step in skip else "not possible here (no %s)" % (
                        "held-out data: scripts/get_data.sh --held-out" if step == "heldout"
                        else "peer drivers: scripts/peers/build.sh --all")
                    print("[results] %s: %s" % (step, why), file=sys.stderr)
                    log.write("%s: %s\n" % (step, why))
                    continue
                argv, extra = cmds[step]
                env = dict(os.environ, **extra)
                print("[results] %s: %s" % (step, shown(argv, extra)), file=sys.stderr)
                log.write("%s: %s\n" % (step, shown(argv, extra)))
                p = subprocess.run(argv, env=env, stdout=subprocess.PIPE, universal_newlines=True)
                with open(os.path.join(out_dir, step + ".md"), "w") as f:
                    f.write(p.stdout)
                if p.returncode != 0:
                    sys.exit("results_table.py: step %s failed (exit %d); its output: %s"
                             % (step, p.returncode, os.path.join(out_dir, step + ".md")))
        with open(os.path.join(out_dir, "machine.txt"), "w") as f:
            f.write("Measured %s on %s.\n" % (datetime.date.today().isoformat(), machine()))
    cpu, table = compose(out_dir)
    where = os.path.join(out_dir, "machine.txt")
    print(open(where).read().strip() if os.path.exists(where) else "Machine not recorded.")
    if cpu:
        print("Speed step: " + cpu)
    print("Each step's table and command: %s" % out_dir)
    print()
    print(table)


if __name__ == "__main__":
    main()
