#!/usr/bin/env python3
"""Keep every Nth laser ring of KITTI .bin scans (and their sibling .label files), to evaluate a
sparser sensor on labelled 64-beam data: N=4 turns an HDL-64E frame into a 16-beam-like one, N=2
into a 32-beam-like one (docs/tuning.md). --fov DEG keeps only the points within DEG/2 of the x
axis in azimuth (a forward-looking sensor's horizontal field of view).

A KITTI .bin lists the points laser by laser, each laser one sweep in azimuth, so a ring ends where
the azimuth wraps from +pi to -pi; a run shorter than MIN_RING points is not counted as a ring of
its own. Output: OUTDIR/<stem>.bin (+ .label), the kept points in input order.

usage: scripts/subsample_rings.py [--fov DEG] N OUTDIR FILE.bin...
"""
import array
import math
import os
import sys

MIN_RING = 100


def main(argv):
    argv = list(argv)
    fov = 360.0
    if len(argv) > 2 and argv[1] == "--fov":
        try:
            fov = float(argv[2])
        except ValueError:
            fov = -1.0
        del argv[1:3]
    if len(argv) < 4 or not argv[1].isdigit() or int(argv[1]) < 1 or not 0 < fov <= 360:
        sys.stderr.write(__doc__)
        return 2
    every, out = int(argv[1]), argv[2]
    os.makedirs(out, exist_ok=True)
    for path in argv[3:]:
        if not subsample(path, every, out, math.radians(fov) / 2):
            return 1
    return 0


def read_scan(path):
    """(points, labels) of a KITTI .bin (float32 x y z intensity records) and its sibling .label
    (uint32 per point; empty when there is none), or None with a message for a malformed pair."""
    pts = array.array("f")
    with open(path, "rb") as f:
        data = f.read()
    if len(data) % 16:
        sys.stderr.write("%s: not KITTI float32 x y z intensity records\n" % path)
        return None
    pts.frombytes(data)
    n = len(pts) // 4
    labs = array.array("I")
    lab_path = os.path.splitext(path)[0] + ".label"
    if os.path.exists(lab_path):
        with open(lab_path, "rb") as f:
            labs.frombytes(f.read())
        if len(labs) != n:
            sys.stderr.write("%s: %d labels for %d points\n" % (lab_path, len(labs), n))
            return None
    return pts, labs


def write_scan(out, path, pts, labs):
    """Writes OUTDIR/<stem of path>.bin and, when labs is not empty, its .label; returns the .bin
    path."""
    stem = os.path.join(out, os.path.splitext(os.path.basename(path))[0])
    with open(stem + ".bin", "wb") as f:
        f.write(pts.tobytes())
    if labs:
        with open(stem + ".label", "wb") as f:
            f.write(labs.tobytes())
    return stem + ".bin"


def subsample(path, every, out, half_fov=math.pi):
    """Writes the kept rings of one scan; False (with a message) for a malformed file."""
    scan = read_scan(path)
    if scan is None:
        return False
    pts, labs = scan
    n = len(pts) // 4
    keep_p, keep_l = array.array("f"), array.array("I")
    ring, run, prev = 0, 0, None
    for i in range(n):
        az = math.atan2(pts[4 * i + 1], pts[4 * i])
        if prev is not None and az - prev < -math.pi and run >= MIN_RING:
            ring, run = ring + 1, 0
        prev, run = az, run + 1
        if ring % every == 0 and abs(az) <= half_fov:
            keep_p.extend(pts[4 * i:4 * i + 4])
            if labs:
                keep_l.append(labs[i])
    write_scan(out, path, keep_p, keep_l)
    print("%s: %d rings, kept %d of %d points" % (os.path.basename(path), ring + 1,
                                                  len(keep_p) // 4, n))
    return True


if __name__ == "__main__":
    sys.exit(main(sys.argv))
