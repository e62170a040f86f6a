#!/usr/bin/env python3
"""Where the GPU pipeline's wall time goes, from a CUPTI trace of cuda/bench/cupti_trace.cpp.

  python3 scripts/gpu_trace_gaps.py TRACE[.gz] --points N [--show 1]

TRACE: lines "<K|C|S|R> <start ns> <end ns> <correlation id> <name>" (kernel, copy, memset,
runtime call); `GF_TRACE=1 bash cuda/run_gpu_checks.sh` writes one (docs/gpu.md). N: the
cloud's points (a KITTI frame 124668): a filter call runs from the cudaSetDevice before the
upload of its 12 N bytes to the end of the host's sync after the download of its N labels.
Prints per call the wall time, the GPU busy time (the union of kernels, copies and memsets),
the time before the first GPU work, the GPU's idle gaps and the runtime calls the host made
during each gap of 3 us or more, then the medians over the calls (the first one left out when
there are more than two: it allocates).
"""
import argparse
import collections
import gzip
import statistics


def read_trace(path):
    """The records (kind, start, end, correlation id, name) of a trace file, .gz or plain."""
    opener = gzip.open if path.endswith(".gz") else open
    recs = []
    with opener(path, "rt") as f:
        for line in f:
            p = line.rstrip("\n").split(" ", 4)
            if len(p) == 5 and p[0] in ("K", "C", "S", "R"):
                recs.append((p[0], int(p[1]), int(p[2]), int(p[3]), p[4]))
    return recs


def filter_calls(recs, points):
    """(start, end) of each filter call of `points` points (see the module's doc)."""
    api = sorted((r for r in recs if r[0] == "R"), key=lambda r: r[1])
    gpu = sorted((r for r in recs if r[0] != "R"), key=lambda r: r[1])
    by_corr = {r[3]: r for r in api}
    uploads = [g for g in gpu if g[0] == "C" and g[4] == "kind1_%d" % (12 * points)]
    downloads = [g for g in gpu if g[0] == "C" and g[4] == "kind2_%d" % points]
    calls = []
    for up in uploads:
        launch = by_corr.get(up[3])
        down = [g for g in downloads if g[1] > up[1]]
        if launch is None or not down:
            continue
        entry = [r for r in api if r[4].startswith("cudaSetDevice") and r[1] <= launch[1]]
        start = entry[-1][1] if entry else launch[1]
        syncs = [r for r in api if "Synchronize" in r[4] and r[2] >= down[0][2]]
        calls.append((start, syncs[0][2] if syncs else down[0][2]))
    return calls


def call_profile(recs, start, end, min_gap_ns=3000):
    """Figures of one call [ns]: wall, busy, kernels and their count, before the first GPU
    work, idle gaps (sum, count, and those of min_gap_ns or more with the host's calls)."""
    gpu = sorted((r for r in recs if r[0] != "R" and r[1] >= start and r[2] <= end),
                 key=lambda r: r[1])
    api = [r for r in recs if r[0] == "R" and r[1] >= start and r[2] <= end]
    busy, gaps, cur = 0, [], None
    for g in gpu:
        if cur is None or g[1] > cur[1]:
            if cur is not None:
                busy += cur[1] - cur[0]
                gaps.append((cur[1], g[1]))
            cur = [g[1], g[2]]
        else:
            cur[1] = max(cur[1], g[2])
    if cur is not None:
        busy += cur[1] - cur[0]
    long_gaps = []
    for a, b in gaps:
        if b - a >= min_gap_ns:
            host = collections.Counter(r[4] for r in api if r[2] > a and r[1] < b)
            long_gaps.append((a - start, b - a, host))
    host_time = collections.Counter()
    for r in api:
        host_time[r[4]] += r[2] - r[1]
    return {
        "wall": end - start,
        "busy": busy,
        "kernels": sum(g[2] - g[1] for g in gpu if g[0] == "K"),
        "kernel_count": sum(1 for g in gpu if g[0] == "K"),
        "before_gpu": (gpu[0][1] if gpu else end) - start,
        "gaps": sum(b - a for a, b in gaps),
        "gap_count": len(gaps),
        "api_calls": len(api),
        "long_gaps": long_gaps,
        "host_time": host_time,
        "timeline": [(g[1] - start, g[2] - g[1], g[4]) for g in gpu],
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("trace")
    ap.add_argument("--points", type=int, required=True, help="points of the traced cloud")
    ap.add_argument("--show", type=int, default=1, help="last calls to print in full")
    args = ap.parse_args()
    recs = read_trace(args.trace)
    calls = filter_calls(recs, args.points)
    print("filter calls of %d points: %d" % (args.points, len(calls)))
    if not calls:
        return 1
    profiles = [call_profile(recs, s, e) for s, e in calls]
    for i, p in enumerate(profiles[-args.show:] if args.show > 0 else []):
        print("\n== call %d: wall %.1f us, GPU busy %.1f us (%d kernels %.1f us), %.1f us before "
              "the first GPU work, %.1f us idle in %d gaps, %d runtime calls"
              % (len(profiles) - args.show + i, p["wall"] / 1e3, p["busy"] / 1e3,
                 p["kernel_count"], p["kernels"] / 1e3, p["before_gpu"] / 1e3, p["gaps"] / 1e3,
                 p["gap_count"], p["api_calls"]))
        for t, d, name in p["timeline"]:
            print("  gpu %8.1f %7.1f %s" % (t / 1e3, d / 1e3, name[:80]))
        print("  gaps of 3 us or more (start, length [us], the host's calls meanwhile):")
        for t, d, host in p["long_gaps"]:
            print("  gap %8.1f %7.1f %s" % (t / 1e3, d / 1e3, ", ".join(
                "%s x%d" % kv for kv in host.most_common(6))))
        print("  host time in runtime calls [us]:")
        for name, ns in p["host_time"].most_common(12):
            print("   %-50s %8.1f" % (name, ns / 1e3))
    kept = profiles[1:] if len(profiles) > 2 else profiles
    print("\nmedians over %d calls [us]:" % len(kept))
    for key in ("wall", "busy", "kernels", "before_gpu", "gaps"):
        print("  %-12s %8.1f" % (key, statistics.median(p[key] for p in kept) / 1e3))
    for key in ("kernel_count", "gap_count", "api_calls"):
        print("  %-12s %8.0f" % (key, statistics.median(p[key] for p in kept)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
