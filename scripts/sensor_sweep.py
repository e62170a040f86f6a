#!/usr/bin/env python3
"""Both methods on sensors the dev data does not have (docs/evaluation.md).

Eight sensors (seven spinning ones, 16 to 128 beams at 900 to 3,600 firings a turn, and a
solid-state one with a non-repeating pattern) in four generated worlds (street, verge,
off-road, trail) at four heights above the ground (0.4, 0.7, 1.2, 1.8 m), two seeds each: 128
sensor placements, 256 scans with exact truth, all from `ground_filter_eval`'s
`builtin:KIND:SEED:layout=...,sensor_height=...` scenes, so nothing needs downloading. Per
placement the F1 of the two seeds pooled; per sensor the mean over its 16 placements; then the
mean and the lowest over all placements, for:

  normal, rules off   the normal-vector method with both sparse-lines rules off
                      (max_line_ratio=0, min_candidate_share=0): how it was before them
  normal              the normal-vector method, defaults (plus --set)
  voxel               the voxel method, defaults

    python3 scripts/sensor_sweep.py                       # the table (a few minutes)
    python3 scripts/sensor_sweep.py --quick               # one seed, heights 0.7 and 1.8
    python3 scripts/sensor_sweep.py --set max_line_ratio=2.6   # the plateau's edges
    python3 scripts/sensor_sweep.py --frame base          # each scan in a frame on the ground
                                                          # below its sensor (base_link)
    python3 scripts/sensor_sweep.py --frame map --sensor-x 40   # in a map frame, 40 m away
    PEER_BIN=DIR python3 scripts/sensor_sweep.py --peers patchworkpp,csf

--peers NAME,... also runs DIR/<name>_driver (scripts/peers/README.md: each driver is built
out of the peer's own code, outside this package) on the same scans, written as KITTI .bin
files by `ground_filter_eval --write-scans`, and scores their labels with `--score-labels`,
each with its own defaults. --height-peers NAME,... runs those again with the true sensor height of each
placement, `--set sensor_height=H` (for drivers that take it: Patchwork++'s and linefit's assume
a fixed height).
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# name, scene kind, its fields: spinning sensors (beams, lowest and highest beam elevation,
# firings a turn) and a solid-state one (a forward disc of non-repeating rays, Livox-like)
SENSORS = [
    ("16 beams +-15 deg, 1,800 firings (VLP-16)", "lidar16",
     "beams=16,vertical_min_deg=-15,vertical_max_deg=15,azimuth_steps=1800"),
    ("32 beams +-15 deg, 3,600 firings", "lidar16",
     "beams=32,vertical_min_deg=-15,vertical_max_deg=15,azimuth_steps=3600"),
    ("32 beams -30.7..+10.7 deg, 2,170 firings (HDL-32E)", "lidar16",
     "beams=32,vertical_min_deg=-30.67,vertical_max_deg=10.67,azimuth_steps=2170"),
    ("16 beams +-15 deg, 900 firings", "lidar16",
     "beams=16,vertical_min_deg=-15,vertical_max_deg=15,azimuth_steps=900"),
    ("32 beams +-15 deg, 1,800 firings", "lidar16",
     "beams=32,vertical_min_deg=-15,vertical_max_deg=15,azimuth_steps=1800"),
    ("64 beams +-16.6 deg, 2,048 firings (OS1-64)", "lidar16",
     "beams=64,vertical_min_deg=-16.6,vertical_max_deg=16.6,azimuth_steps=2048"),
    ("128 beams +-22.5 deg, 2,048 firings (OS1-128)", "lidar16",
     "beams=128,vertical_min_deg=-22.5,vertical_max_deg=22.5,azimuth_steps=2048"),
    ("solid-state 70.4 deg disc, 24 k rays a frame (Livox Avia-like)", "rosette",
     "rosette_fov_deg=70.4,rosette_rays=24000"),
]
WORLDS = ["street", "verge", "offroad", "trail"]
RULES_OFF = ["--set", "max_line_ratio=0", "--set", "min_candidate_share=0"]


FRAMES = {"sensor": "", "base": ",base_frame=1", "map": ",world_frame=1"}


def scene(sensor, world, height, seed, frame="sensor", sensor_x=0.0):
    _, kind, fields = sensor
    return "builtin:%s:%d:layout=%s,%s,sensor_height=%g%s%s" % (
        kind, seed, world, fields, height, ",sensor_x=%g" % sensor_x if sensor_x else "",
        FRAMES[frame])


def run_json(cmd):
    """The per-file JSON objects of a `ground_filter_eval --json` call."""
    out = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         universal_newlines=True)
    if out.returncode != 0:
        sys.exit("%s: %s failed (%d):\n%s" % (os.path.basename(sys.argv[0]), cmd[0],
                                                out.returncode, out.stderr))
    return json.loads(out.stdout)["files"]


def peer_bin():
    """Where the peers' drivers are: $PEER_BIN, else the build folder of scripts/peers/."""
    return os.environ.get("PEER_BIN", os.path.join(
        os.environ.get("GF_PEERS_DIR", os.path.expanduser("~/.cache/ground_filter_peers")),
        "build"))


def f1(files):
    tp = sum(f["tp"] for f in files)
    fp = sum(f["fp"] for f in files)
    fn = sum(f["fn"] for f in files)
    return 100.0 * 2 * tp / (2 * tp + fp + fn) if tp else 0.0


def strides(files):
    """The sample_stride a widened scan ran with, from its note ('sample_stride 2 -> 4: ...')."""
    out = set()
    for f in files:
        note = f.get("note") or ""
        out.add(note.split(":")[0].split("-> ")[-1] if note.startswith("sample_stride") else "-")
    return "/".join(sorted(out))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="one seed, heights 0.7 and 1.8 m")
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                    help="parameter of the 'normal' column (repeatable)")
    ap.add_argument("--peers", default="", help="comma-separated peer drivers in $PEER_BIN")
    ap.add_argument("--height-peers", default="", metavar="NAME,...",
                    help="of --peers: also run these with --set sensor_height=H, the "
                    "placement's true height (a column 'NAME, true height')")
    ap.add_argument("--eval", default=os.environ.get("GF_EVAL", os.path.join(
        ROOT, ".ws", "devel", "lib", "ground_filter", "ground_filter_eval")))
    ap.add_argument("--json", action="store_true", help="print the F1 of every placement")
    ap.add_argument("--frame", choices=sorted(FRAMES), default="sensor",
                    help="each scan in its sensor's frame, a frame on the ground below it "
                    "(base: base_link) or the world frame (map: the origin on the ground at x=0)")
    ap.add_argument("--methods", default="rules-off,normal,voxel", metavar="M,...",
                    help="columns to run, of rules-off, normal, voxel (all by default)")
    ap.add_argument("--sensor-x", type=float, default=0.0,
                    help="the sensor this far along the world's x (with --frame map: so far "
                    "from the origin) [m]")
    args = ap.parse_args()
    if not os.access(args.eval, os.X_OK):
        sys.exit("sensor_sweep.py: %s not built (bash -c 'source scripts/common.sh; gf_build')"
                 % args.eval)
    seeds = [1] if args.quick else [1, 2]
    heights = [0.7, 1.8] if args.quick else [0.4, 0.7, 1.2, 1.8]
    peers = [p for p in args.peers.split(",") if p]
    height_peers = [p for p in args.height_peers.split(",") if p]
    if not set(height_peers) <= set(peers):
        sys.exit("sensor_sweep.py: --height-peers must name peers of --peers")
    bin_dir = peer_bin()
    for p in peers:
        if not os.access(os.path.join(bin_dir, p + "_driver"), os.X_OK):
            sys.exit("sensor_sweep.py: no %s/%s_driver (scripts/peers/README.md)" % (bin_dir, p))
    extra = [a for s in args.set for a in ("--set", s)]
    configs = [("normal, rules off", ["--method", "normal"] + RULES_OFF),
               ("normal", ["--method", "normal"] + extra), ("voxel", ["--method", "voxel"])]
    methods = [m for m in args.methods.split(",") if m]
    known = {"rules-off": configs[0], "normal": configs[1], "voxel": configs[2]}
    if not methods or not set(methods) <= set(known):
        sys.exit("sensor_sweep.py: --methods takes rules-off, normal, voxel")
    configs = [c for m, c in known.items() if m in methods]
    runs = [(p, p, None) for p in peers] + [(p + ", true height", p, True) for p in height_peers]
    names = [c[0] for c in configs] + [r[0] for r in runs]
    rows, placements = [], []
    tmp = tempfile.TemporaryDirectory()
    for sensor in SENSORS:
        cells = [(w, h) for w in WORLDS for h in heights]
        paths = [scene(sensor, w, h, s, args.frame, args.sensor_x) for w, h in cells
                 for s in seeds]
        per = {}  # column -> list of per-file JSON in the order of paths
        for i, (name, opts) in enumerate(configs):
            cmd = [args.eval, "--json"] + opts + paths
            if i == 0 and peers:
                cmd[1:1] = ["--write-scans", tmp.name]
            per[name] = run_json(cmd)
        # the files --write-scans wrote, as the eval names them
        bins = [r["scan_file"] for r in per[configs[0][0]]] if peers else []
        heights_of = [h for _, h in cells for _ in seeds]
        for name, p, true_height in runs:
            out = os.path.join(tmp.name, name.replace(", ", "_").replace(" ", "_"))
            os.makedirs(out, exist_ok=True)
            driver = [os.path.join(bin_dir, p + "_driver"), "--out", out, "--repeats", "1"]
            for h in sorted(set(heights_of)) if true_height else [None]:
                sets = ["--set", "sensor_height=%g" % h] if h is not None else []
                files = [b for b, bh in zip(bins, heights_of) if h is None or bh == h]
                subprocess.run(driver + sets + files, check=True, stdout=subprocess.DEVNULL)
            per[name] = run_json([args.eval, "--json", "--score-labels", out] + paths)
        n = len(seeds)
        cell_f1 = {name: [f1(per[name][k * n:(k + 1) * n]) for k in range(len(cells))]
                   for name in names}
        for k, (w, h) in enumerate(cells):
            placements.append({"sensor": sensor[0], "world": w, "height": h,
                               **{name: round(cell_f1[name][k], 2) for name in names}})
        rows.append((sensor[0], strides(per["normal"]) if "normal" in per else "-",
                     [sum(cell_f1[name]) / len(cells) for name in names]))
    if args.json:
        print(json.dumps(placements, indent=1))
        return
    print("F1 %% (ground = positive), mean over %d worlds x %d heights, seeds %s pooled"
          % (len(WORLDS), len(heights), ",".join(map(str, seeds))))
    print("| sensor | normal stride | " + " | ".join(names) + " |")
    print("|---" * (len(names) + 2) + "|")
    for sensor, stride, means in rows:
        print("| %s | %s | %s |" % (sensor, stride, " | ".join("%.1f" % m for m in means)))
    allv = {name: [p[name] for p in placements] for name in names}
    print("| all %d placements: mean | | %s |" % (
        len(placements), " | ".join("%.1f" % (sum(v) / len(v)) for v in allv.values())))
    print("| all %d placements: lowest | | %s |" % (
        len(placements), " | ".join("%.1f" % min(v) for v in allv.values())))
    if not {"normal, rules off", "normal"} <= set(allv):
        print("command: %s" % " ".join(["python3", "scripts/sensor_sweep.py"] + sys.argv[1:]))
        return
    before, after = allv["normal, rules off"], allv["normal"]
    changed = sum(1 for b, a in zip(before, after) if b != a)
    lost = sum(1 for b, a in zip(before, after) if a < b)
    print("normal against rules off: %d of %d placements changed, %d lower (largest drop %.2f)"
          % (changed, len(before), lost, max([b - a for b, a in zip(before, after)] + [0.0])))
    print("command: %s" % " ".join(["python3", "scripts/sensor_sweep.py"] + sys.argv[1:]))


if __name__ == "__main__":
    main()
