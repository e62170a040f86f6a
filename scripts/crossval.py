#!/usr/bin/env python3
"""Leave-one-group-out check of every default fitted on the dev data (docs/evaluation.md).

For each parameter below, the eval tool scores every dev group at each value of a grid around
the default. Then, for each group G, the value is chosen again on the other groups alone (best
mean F1 over them) and G's F1 at that value is printed against G's F1 at the default. A default
whose left-out choice moves a left-out group by more than --limit (0.3 F1 points) is flagged:
such a default is fitted to that group rather than sitting on a plateau shared by all.

    python3 scripts/crossval.py                 # every parameter, both methods
    python3 scripts/crossval.py --only normal:k,voxel:plane_distance
    python3 scripts/crossval.py --quick         # one seed per generated family, short grids
    python3 scripts/crossval.py --list          # the parameters and grids, no run

The auto cuts of scan_type (a compile-time rule, docs/scan_types.md) are checked the same way
without re-running per value: every file is scored once in each forced mode (scan_type=ground,
scan_type=airborne) and the cut picks, per file, the mode it would decide from the file's
measures (--scan-measures).

Ground-level parameters are scored on the ground-level groups only and the airborne ones
(morph_*) on the airborne groups only: scan_type auto runs the other groups in the other mode,
where the parameter is not read (plane_distance below 0.5 m included: the airborne threshold
is at least 0.5 m). Results are cached per run in --cache (JSON) so an interrupted run resumes.
Data: $GF_DATA_DIR, else data/ (scripts/get_data.sh), else ../shared/data.
"""
import argparse
import json
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def data_dir():
    env = os.environ.get("GF_DATA_DIR")
    if env:
        if not os.path.isdir(env):
            sys.exit("crossval.py: GF_DATA_DIR=%s is no folder" % env)
        return env
    for d in (os.path.join(ROOT, "data"), os.path.join(ROOT, "..", "shared", "data")):
        if os.path.isdir(d):
            return os.path.normpath(d)
    sys.exit("crossval.py: no data: run scripts/get_data.sh (or set GF_DATA_DIR)")


def groups(data, quick):
    seeds = [1] if quick else [1, 2]
    k = os.path.join(data, "semantickitti", "seq00")
    gen = lambda kind: ["builtin:%s:%d" % (kind, s) for s in seeds]
    ground = [
        ("kitti", [os.path.join(k, "%06d.bin" % i) for i in range(3)]),
        ("offroad", [os.path.join(data, "offroad")]),
        ("gen street", gen("lidar")),
        ("gen verge", gen("verge")),
        ("gen offroad", gen("offroad")),
        ("gen trail", gen("trail")),
        ("gen mls", ["builtin:mls:1"]),
        # Sparse spinning sensors (scripts/sensor_sweep.py): a VLP-16 0.7 m up, 32 beams at
        # 3,600 firings 1.8 m up.
        ("gen 16-beam", gen("lidar16")),
        ("gen 32-beam", ["builtin:lidar16:%d:beams=32,azimuth_steps=3600,sensor_height=1.8" % s
                         for s in seeds]),
    ]
    airborne = [
        ("isprs", [os.path.join(data, "isprs")]),
        ("airborne", [os.path.join(data, "airborne")]),
        ("gen airborne", gen("airborne")),
    ]
    return ground, airborne


# (method, parameter, default, grid, which groups). Grids bracket the default on both sides.
PARAMS = [
    ("voxel", "plane_distance", 0.15, [0.08, 0.10, 0.12, 0.15, 0.20, 0.25], "ground"),
    ("voxel", "flatness_threshold", 0.08, [0.02, 0.03, 0.04, 0.06, 0.08, 0.10, 0.12, 0.16], "ground"),
    ("voxel", "height_margin", 1.0, [0.5, 0.75, 1.0, 1.5, 2.0], "ground"),
    ("voxel", "seed_window", 0.2, [0.1, 0.15, 0.2, 0.3, 0.4], "ground"),
    ("voxel", "tile_size", 1.0, [0.5, 1.0, 2.0, 4.0], "ground"),
    ("voxel", "max_slope_deg", 30.0, [20.0, 25.0, 30.0, 35.0, 40.0], "ground"),
    ("voxel", "morph_slope", 0.1, [0.05, 0.075, 0.1, 0.15, 0.2], "airborne"),
    ("normal", "k", 40, [24, 32, 40, 48, 56], "ground"),
    ("normal", "sample_stride", 2, [1, 2, 3, 4], "ground"),
    ("normal", "plane_distance", 0.15, [0.08, 0.10, 0.12, 0.15, 0.20, 0.25], "ground"),
    ("normal", "tile_size", 4.0, [2.0, 3.0, 4.0, 6.0, 8.0], "ground"),
    ("normal", "floor_share", 0.15, [0.0, 0.05, 0.10, 0.15, 0.20, 0.30], "ground"),
    ("normal", "local_ground_min", 8, [0, 4, 8, 12, 16], "ground"),
    ("normal", "local_ground_below", 0.10, [0.05, 0.10, 0.15, 0.20], "ground"),
    ("normal", "local_ground_above", 0.05, [0.0, 0.025, 0.05, 0.10], "ground"),
    ("normal", "max_line_ratio", 3.0, [0.0, 1.5, 2.0, 3.0, 4.0, 6.0], "ground"),
    ("normal", "min_candidate_share", 0.05, [0.0, 0.02, 0.05, 0.10, 0.20], "ground"),
    ("normal", "morph_slope", 0.1, [0.05, 0.075, 0.1, 0.15, 0.2], "airborne"),
]
# scan_type auto's cuts (ScanTypeClassifier in src/core/airborne/scan_type.h): rule 3's share
# of the densest tenth of the cells, rule 4's share of the densest tenth of the 1 m columns and
# its least points per column.
CUTS = [
    ("auto", "concentrated", 0.40, [0.30, 0.34, 0.37, 0.40, 0.45, 0.50]),
    ("auto", "column_concentrated", 0.32, [0.26, 0.28, 0.30, 0.32, 0.34, 0.36, 0.38]),
    ("auto", "min_column_mean", 4.0, [1.0, 2.0, 4.0, 8.0, 16.0, 32.0]),
]
DEFAULT_CUTS = {name: d for _, name, d, _ in CUTS}


def f1(c):
    tp, fp, fn = c
    return 100.0 * 2 * tp / (2 * tp + fp + fn) if tp + fp + fn else float("nan")


def run_eval(tool, method, sets, paths, measures=False):
    cmd = [tool, "--json", "--method", method]
    for name, value in sets:
        cmd += ["--set", "%s=%s" % (name, value)]
    if measures:
        cmd.append("--scan-measures")
    out = subprocess.run(cmd + paths, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         universal_newlines=True)
    if out.returncode != 0:
        sys.exit("crossval.py: %s failed: %s" % (" ".join(cmd), out.stderr.strip()))
    return json.loads(out.stdout)["files"]


def counts(files):
    """(tp, fp, fn) summed over the labelled files."""
    tp = sum(f["tp"] for f in files if f.get("labelled"))
    fp = sum(f["fp"] for f in files if f.get("labelled"))
    fn = sum(f["fn"] for f in files if f.get("labelled"))
    return (tp, fp, fn)


class Cache:
    def __init__(self, path):
        self.path = path
        self.data = {}
        if path and os.path.exists(path):
            with open(path) as f:
                self.data = json.load(f)

    def get(self, key, make):
        if key not in self.data:
            self.data[key] = make()
            if self.path:
                tmp = self.path + ".tmp"
                with open(tmp, "w") as f:
                    json.dump(self.data, f)
                os.replace(tmp, self.path)
        return self.data[key]


def leave_one_out(table, default, limit):
    """table: {group: {value: F1}} -> rows (group, chosen value, F1 there, F1 at default, delta)
    and the worst |delta|."""
    rows, worst = [], 0.0
    values = sorted(next(iter(table.values())).keys())
    for g in table:
        others = [h for h in table if h != g]
        if not others:
            continue
        score = lambda v: sum(table[h][v] for h in others) / len(others)
        best = max(values, key=lambda v: (score(v), -abs(v - default)))
        d = table[g][best] - table[g][default]
        worst = max(worst, abs(d))
        rows.append((g, best, table[g][best], table[g][default], d))
    return rows, worst


def plateau(table, default, tol=0.1):
    """Per group: the grid values within tol of that group's best F1, as 'lo..hi'."""
    out = {}
    for g, by_v in table.items():
        best = max(by_v.values())
        ok = sorted(v for v, x in by_v.items() if x >= best - tol)
        out[g] = "%g..%g%s" % (ok[0], ok[-1], "" if default in ok else " (default outside)")
    return out


def print_param(title, table, default, limit):
    rows, worst = leave_one_out(table, default, limit)
    plat = plateau(table, default)
    flag = "MOVES > %.1f" % limit if worst > limit else "ok"
    print("\n### %s (default %g): worst left-out change %.2f, %s" % (title, default, worst, flag))
    print("| left-out group | value chosen without it | its F1 there | its F1 at the default "
          "| change | its plateau (within 0.1 of its best) |")
    print("|---|---|---|---|---|---|")
    for g, v, fv, fd, d in rows:
        print("| %s | %g | %.2f | %.2f | %+.2f | %s |" % (g, v, fv, fd, d, plat[g]))
    values = sorted(next(iter(table.values())).keys())
    print("\nF1 per value: | group | %s |" % " | ".join("%g" % v for v in values))
    for g, by_v in table.items():
        print("| %s | %s |" % (g, " | ".join("%.2f" % by_v[v] for v in values)))
    return worst


def decide(m, cuts):
    """The mode scan_type auto picks from a file's measures (rules 3-4 of docs/scan_types.md;
    rule 2, the nadir view from the origin, is left as it is)."""
    if m["steep_share"] >= 0.5 and m["steep_depth"] >= 8.0:
        return "airborne"
    if m["top_share"] >= cuts["concentrated"]:
        return "ground"
    if (m["column_mean"] >= cuts["min_column_mean"] and
            m["column_top_share"] >= cuts["column_concentrated"]):
        return "ground"
    return "airborne"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--eval", default=os.environ.get(
        "GF_EVAL", os.path.join(ROOT, ".ws", "devel", "lib", "ground_filter", "ground_filter_eval")))
    ap.add_argument("--only", default="", help="METHOD:PARAM[,...] (auto:concentrated, ...)")
    ap.add_argument("--quick", action="store_true", help="one seed per generated family")
    ap.add_argument("--limit", type=float, default=0.3)
    ap.add_argument("--cache", default="", help="JSON file keeping finished runs")
    ap.add_argument("--list", action="store_true")
    a = ap.parse_args()
    only = set(x for x in a.only.split(",") if x)
    chosen = [p for p in PARAMS if not only or "%s:%s" % (p[0], p[1]) in only]
    cuts = [c for c in CUTS if not only or "auto:%s" % c[1] in only]
    if a.list:
        for m, name, d, grid, kind in chosen:
            print("%s:%s default %g grid %s (%s groups)" % (m, name, d, grid, kind))
        for _, name, d, grid in cuts:
            print("auto:%s default %g grid %s" % (name, d, grid))
        return 0
    if not os.access(a.eval, os.X_OK):
        sys.exit("crossval.py: %s not built (bash -c 'source scripts/common.sh; gf_build')" % a.eval)
    ground, airborne = groups(data_dir(), a.quick)
    cache = Cache(a.cache)
    flagged = []
    print("# Leave-one-group-out check of the fitted defaults (F1 %%, pooled per group; "
          "limit %.1f)" % a.limit)
    for method, name, default, grid, kind in chosen:
        gs = ground if kind == "ground" else airborne
        paths = [p for _, ps in gs for p in ps]
        table = {g: {} for g, _ in gs}
        for v in grid:
            key = "%s|%s|%r|%s" % (method, name, v, a.quick)
            files = cache.get(key, lambda: run_eval(a.eval, method, [(name, v)], paths))
            i = 0
            for g, ps in gs:
                # A folder expands to several files: take this group's files by path prefix.
                mine = [f for f in files if any(f["file"].startswith(p) for p in ps)]
                table[g][v] = f1(counts(mine))
                i += len(mine)
        if print_param("%s %s" % (method, name), table, default, a.limit) > a.limit:
            flagged.append("%s:%s" % (method, name))
    if cuts:
        gs = ground + airborne + [("gen registered", ["builtin:stations:1", "builtin:slam:1",
                                                      "builtin:tls_far:1"]),
                                  ("gen nadir hard", ["builtin:uav:1", "builtin:corridor:1"])]
        paths = [p for _, ps in gs for p in ps]
        for method in ("voxel", "normal"):
            runs = {}
            for mode in ("ground", "airborne"):
                key = "%s|scan_type=%s|%s" % (method, mode, a.quick)
                runs[mode] = cache.get(key, lambda: run_eval(
                    a.eval, method, [("scan_type", mode)], paths, measures=True))
            for _, name, default, grid in cuts:
                table = {g: {} for g, _ in gs}
                for v in grid:
                    cut = dict(DEFAULT_CUTS)
                    cut[name] = v
                    for g, ps in gs:
                        tot = [0, 0, 0]
                        for fg, fa in zip(runs["ground"], runs["airborne"]):
                            if not any(fg["file"].startswith(p) for p in ps):
                                continue
                            pick = fg if decide(fg["scan_measures"], cut) == "ground" else fa
                            if pick.get("labelled"):
                                tot = [tot[0] + pick["tp"], tot[1] + pick["fp"],
                                       tot[2] + pick["fn"]]
                        table[g][v] = f1(tot)
                if print_param("%s auto %s" % (method, name), table, default, a.limit) > a.limit:
                    flagged.append("%s:auto:%s" % (method, name))
    print("\nflagged: %s" % (", ".join(flagged) if flagged else "none"))
    return 1 if flagged else 0


if __name__ == "__main__":
    sys.exit(main())
