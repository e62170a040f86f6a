#!/usr/bin/env python3
"""Write changed copies of labelled KITTI .bin scans (and their sibling .label files), to check a
filter on clouds that another node has already processed (docs/tuning.md, "Clouds other nodes
made"):

  --voxel LEAF        keep the first point (input order) of each LEAF-metre cube, as a VoxelGrid
                      downsampling does (one point a cube; the first keeps its own label)
  --keep FRAC         keep a random FRAC of the points (--seed S, default 1)
  --shift DX DY DZ    move every point by (DX, DY, DZ) m: another frame origin, e.g. DZ 1.73 for
                      a base_link on the road under a KITTI sensor, or map coordinates
  --tilt ROLL PITCH   rotate about x by ROLL, then about y by PITCH (degrees, about the origin): a
                      sensor mounted tilted, without a gravity frame
  --crop X0 X1 Y0 Y1 Z0 Z1
                      keep only the points inside the box (m, in the input frame), as
                      pcl::CropBox or Autoware's crop_box_filter before the ground filter: a
                      region of interest, a forward half (--crop 0 1e9 -1e9 1e9 -1e9 1e9)
  --cut X0 X1 Y0 Y1 Z0 Z1
                      drop the points inside the box (CropBox with setNegative): the own
                      vehicle or robot
  --mirror FRAC       add FRAC x the scan's points as reflections under the road: random points
                      more than 0.5 m above KITTI's road (z > -1.23 m) mirrored in its plane
                      z = -1.73 m (wet asphalt, glass), labelled 1 "outlier" (left out of every
                      count: they show what the extra points do to the others)

SemanticKITTI's protocol counts vegetation (class 70) as ground only below -0.75 x the sensor
height (z < -1.2975 m), which --shift and --tilt would move: vegetation is written as 72
"terrain" where the input point satisfied that rule and as 99 "other-object" where it did not,
so the truth reads back unchanged (instance bits kept). Output: OUTDIR/<stem>.bin (+ .label), the
kept points in input order (reflections after them); the options apply in the order above.

usage: scripts/derive_scans.py [--voxel LEAF] [--keep FRAC [--seed S]] [--crop X0 X1 Y0 Y1 Z0 Z1]
                               [--cut X0 X1 Y0 Y1 Z0 Z1] [--shift DX DY DZ]
                               [--tilt ROLL PITCH] [--mirror FRAC] OUTDIR FILE.bin...
"""
import array
import math
import os
import random
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from subsample_rings import read_scan, write_scan  # noqa: E402 (one KITTI scan reader)

VEGETATION, TERRAIN, OTHER_OBJECT, OUTLIER = 70, 72, 99, 1
KITTI_ROAD_Z = -1.73  # KITTI's sensor height above the road [m]
VEGETATION_GROUND_Z = 0.75 * KITTI_ROAD_Z  # SemanticKITTI protocol


def parse(argv):
    """Options and files from argv, or None (usage)."""
    opt = {"voxel": None, "keep": None, "seed": 1, "crop": None, "cut": None, "shift": None,
           "tilt": None, "mirror": None}
    args = list(argv[1:])
    arity = {"--voxel": 1, "--keep": 1, "--seed": 1, "--crop": 6, "--cut": 6, "--shift": 3,
             "--tilt": 2, "--mirror": 1}
    while args and args[0] in arity:
        name, k = args[0], arity[args[0]]
        if len(args) < k + 1:
            return None
        try:
            vals = [float(v) for v in args[1:k + 1]]
        except ValueError:
            return None
        if not all(math.isfinite(v) for v in vals):
            return None
        opt[name[2:]] = vals if k > 1 else vals[0]
        del args[:k + 1]
    if opt["voxel"] is not None and not opt["voxel"] > 0:
        return None
    if opt["keep"] is not None and not 0 < opt["keep"] <= 1:
        return None
    if opt["mirror"] is not None and not 0 <= opt["mirror"] <= 0.5:
        return None
    for box in (opt["crop"], opt["cut"]):
        if box is not None and not all(box[a] < box[a + 1] for a in (0, 2, 4)):
            return None  # an empty box: each lower bound must lie below its upper one
    if len(args) < 2:
        return None
    return opt, args[0], args[1:]


def derive(path, opt, out):
    """Writes the changed copy of one scan; False (with a message) for a malformed file."""
    scan = read_scan(path)
    if scan is None:
        return False
    pts, labs = scan
    n = len(pts) // 4
    keep = range(n)
    if opt["voxel"] is not None:
        leaf, seen, kept = opt["voxel"], set(), []
        for i in keep:
            cell = tuple(math.floor(pts[4 * i + a] / leaf) if math.isfinite(pts[4 * i + a])
                         else None for a in range(3))
            if cell not in seen:
                seen.add(cell)
                kept.append(i)
        keep = kept
    rng = random.Random(opt["seed"])
    if opt["keep"] is not None:
        keep = sorted(rng.sample(list(keep), int(round(len(keep) * opt["keep"]))))
    if opt["crop"] is not None:
        keep = [i for i in keep if inside(pts, i, opt["crop"])]
    if opt["cut"] is not None:
        keep = [i for i in keep if not inside(pts, i, opt["cut"])]
    mirrored = []
    if opt["mirror"]:
        above = [i for i in keep if pts[4 * i + 2] > KITTI_ROAD_Z + 0.5]
        mirrored = rng.sample(above, min(len(above), int(round(len(keep) * opt["mirror"]))))
    rot = rotation(opt["tilt"])
    shift = opt["shift"] or [0.0, 0.0, 0.0]
    out_p, out_l = array.array("f"), array.array("I")
    for i, reflection in [(i, False) for i in keep] + [(i, True) for i in mirrored]:
        x, y, z, w = pts[4 * i:4 * i + 4]
        if reflection:
            z = 2 * KITTI_ROAD_Z - z
        if rot:
            x, y, z = (sum(rot[r][c] * v for c, v in enumerate((x, y, z))) for r in range(3))
        out_p.extend((x + shift[0], y + shift[1], z + shift[2], w))
        if labs:
            lab = labs[i]
            if reflection:
                lab = OUTLIER
            elif lab & 0xFFFF == VEGETATION and (opt["shift"] or rot):
                cls = TERRAIN if pts[4 * i + 2] < VEGETATION_GROUND_Z else OTHER_OBJECT
                lab = (lab & 0xFFFF0000) | cls
            out_l.append(lab)
    bin_path = write_scan(out, path, out_p, out_l)
    print("%s: %d of %d points%s -> %s" % (path, len(keep), n,
                                          " + %d reflections" % len(mirrored) if mirrored else "",
                                          bin_path))
    return True


def inside(pts, i, box):
    """Point i lies in the box (bounds included; NaN never does)."""
    return all(box[2 * a] <= pts[4 * i + a] <= box[2 * a + 1] for a in range(3))


def rotation(tilt):
    """R = Ry(pitch) Rx(roll) as rows, or None."""
    if not tilt:
        return None
    r, p = math.radians(tilt[0]), math.radians(tilt[1])
    rx = [[1, 0, 0], [0, math.cos(r), -math.sin(r)], [0, math.sin(r), math.cos(r)]]
    ry = [[math.cos(p), 0, math.sin(p)], [0, 1, 0], [-math.sin(p), 0, math.cos(p)]]
    return [[sum(ry[i][k] * rx[k][j] for k in range(3)) for j in range(3)] for i in range(3)]


def main(argv):
    parsed = parse(argv)
    if parsed is None:
        sys.stderr.write(__doc__)
        return 2
    opt, out, files = parsed
    os.makedirs(out, exist_ok=True)
    for path in files:
        if not derive(path, opt, out):
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
