#!/usr/bin/env python3
"""Converts a PCD (ascii, binary or binary_compressed) to KITTI-style .bin records (x y z 0, float32).

The GPU machine's build (cuda/run_gpu_checks.sh) has no PCL; its benchmark and tests
read the Ouster OS-128 scan from .carry/data/os128_000000.bin, made with:
    python3 scripts/pcd_to_kitti_bin.py data/unlabelled/os128_000000.pcd \\
        .carry/data/os128_000000.bin
Every record is kept, non-finite points included (the filter's own NaN rule applies to them).
"""
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from make_bag import read_pcd  # noqa: E402  (the project's one PCD reader)


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 2:
        sys.stderr.write("usage: pcd_to_kitti_bin.py IN.pcd OUT.bin\n")
        return 2
    scan = read_pcd(argv[0])
    offsets = {name: off for name, off, _dtype, _count in scan.fields}
    n = scan.width * scan.height
    rec = np.frombuffer(scan.data, dtype=np.uint8).reshape(n, scan.point_step)
    out = np.zeros((n, 4), dtype="<f4")
    for col, name in enumerate("xyz"):
        out[:, col] = rec[:, offsets[name]:offsets[name] + 4].copy().view("<f4")[:, 0]
    out.tofile(argv[1])
    print("%s: %d points -> %s" % (argv[0], n, argv[1]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
