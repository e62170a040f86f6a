#!/usr/bin/env python3
"""Writes the seed corpus of the PointCloud2 fuzz target (test/fuzz_point_cloud2.cpp).

Each file is one serialised sensor_msgs/PointCloud2 (as it travels on a ROS connection), valid
ones and malformed ones. Small on purpose (a few KB). Regenerate with:
  python3 test/fuzz_make_corpus.py [--data DATA] [--out test/fuzz_corpus]
(DATA: the data folder, default as scripts/gf_data.py: $GF_DATA_DIR, data/, ../shared/data)
Crash reproducers found by scripts/fuzz.sh are added to the same folder as crash-*, and inputs
that were once too slow (a libFuzzer timeout) as slow-*.
"""
import argparse
import io
import math
import os
import struct
import sys

from sensor_msgs.msg import PointCloud2, PointField
from std_msgs.msg import String

HERE = os.path.dirname(os.path.realpath(__file__))
F32, F64, U8, U16 = PointField.FLOAT32, PointField.FLOAT64, PointField.UINT8, PointField.UINT16


def field(name, offset, datatype, count=1):
    return PointField(name=name, offset=offset, datatype=datatype, count=count)


def cloud(points, fields, point_step, pack, width=None, height=1, row_pad=0, seq=0):
    """points: list of tuples; pack(p) -> bytes of one record (<= point_step, zero padded)."""
    c = PointCloud2()
    c.header.seq = seq
    c.header.frame_id = "velodyne"
    c.height = height
    c.width = width if width is not None else len(points) // max(height, 1)
    c.fields = fields
    c.is_bigendian = False
    c.point_step = point_step
    c.row_step = c.width * point_step + row_pad
    data = bytearray()
    for r in range(c.height):
        for col in range(c.width):
            rec = pack(points[r * c.width + col])
            data += rec + b"\0" * (point_step - len(rec))
        data += b"\xab" * row_pad
    c.data = bytes(data)
    c.is_dense = all(all(math.isfinite(v) for v in p[:3]) for p in points)
    return c


def serialize(msg):
    buf = io.BytesIO()
    msg.serialize(buf)
    return buf.getvalue()


def kitti_points(data_dir, step=400):
    path = os.path.join(data_dir, "semantickitti", "seq00", "000000.bin")
    with open(path, "rb") as f:
        raw = f.read()
    n = len(raw) // 16
    return [struct.unpack_from("<4f", raw, 16 * i) for i in range(0, n, step)]


def xyzi(p):
    return struct.pack("<4f", *p[:4])


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=None)
    ap.add_argument("--out", default=os.path.join(HERE, "fuzz_corpus"))
    a = ap.parse_args()
    if a.data is None:
        sys.path.insert(0, os.path.join(HERE, "..", "scripts"))
        from gf_data import NoDataError, data_dir
        try:
            a.data = data_dir()
        except NoDataError as e:
            sys.exit("fuzz_make_corpus.py: %s" % e)
    os.makedirs(a.out, exist_ok=True)
    pts = kitti_points(a.data)  # ~310 points of a real scan, ground and objects
    base_fields = [field("x", 0, F32), field("y", 4, F32), field("z", 8, F32),
                   field("intensity", 12, F32)]
    nan, inf = float("nan"), float("inf")
    seeds = {}

    seeds["valid_unorganised_kitti"] = cloud(pts, base_fields, 16, xyzi)
    seeds["valid_transformed_kitti"] = cloud(pts, base_fields, 16, xyzi, seq=1)
    grid = pts[:300]
    ring_fields = base_fields + [field("ring", 16, U16)]
    seeds["valid_organised_row_padding"] = cloud(
        grid, ring_fields, 20, lambda p: xyzi(p) + struct.pack("<H", 7), width=60, height=5,
        row_pad=12)
    extra = [field("intensity", 0, F32), field("z", 4, F32), field("x", 8, F32),
             field("y", 12, F32), field("t", 16, F64), field("ring", 24, U16),
             field("ground", 26, U8)]
    seeds["valid_extra_fields_reordered"] = cloud(
        pts, extra, 28, lambda p: struct.pack("<4fdHB", p[3], p[2], p[0], p[1], 1.5, 3, 9))
    with_nan = [(nan, p[1], p[2], p[3]) if i % 7 == 0 else
                (p[0], inf, p[2], p[3]) if i % 11 == 0 else p for i, p in enumerate(pts)]
    seeds["valid_nan_inf_points"] = cloud(with_nan, base_fields, 16, xyzi)
    far = list(pts) + [(1e30, 0.0, 0.0, 0.0), (0.0, 3e5, 0.0, 0.0), (0.0, 0.0, -1e7, 0.0)]
    seeds["valid_far_points"] = cloud(far, base_fields, 16, xyzi)
    seeds["valid_empty"] = cloud([], base_fields, 16, xyzi, width=0, height=0)
    same = [(1.0, 2.0, 3.0, 0.0)] * 60
    seeds["valid_all_same_point"] = cloud(same, base_fields, 16, xyzi)
    shared = [field("x", 0, F32), field("y", 0, F32), field("z", 0, F32)]
    seeds["valid_xyz_same_offset"] = cloud(pts[:50], shared, 4, lambda p: struct.pack("<f", p[0]))
    f64_fields = [field("x", 0, F64), field("y", 8, F64), field("z", 16, F64),
                  field("intensity", 24, F32)]
    with_far = list(pts) + [(1e300, 0.0, 0.0, 0.0), (nan, 1.0, 2.0, 0.0)]
    seeds["valid_float64_xyz"] = cloud(with_far, f64_fields, 28,
                                       lambda p: struct.pack("<3df", p[0], p[1], p[2], p[3]))

    bad = cloud(pts[:40], base_fields, 16, xyzi)
    bad.data = bad.data[:-10]
    seeds["bad_short_data"] = bad
    bad = cloud(pts[:40], base_fields, 16, xyzi)
    bad.width, bad.height, bad.row_step = 0x40000000, 1, 16  # width * point_step > 2^32
    seeds["bad_row_step_overflow"] = bad
    bad = cloud(pts[:40], base_fields, 16, xyzi)
    bad.height, bad.row_step = 0x7FFFFFFF, 0x7FFFFFFF
    seeds["bad_height_overflow"] = bad
    seeds["bad_missing_z"] = cloud(pts[:40], base_fields[:2] + base_fields[3:], 16, xyzi)
    seeds["bad_mistyped_x"] = cloud(pts[:40], [field("x", 0, F64)] + base_fields[1:], 16, xyzi)
    seeds["bad_count_y"] = cloud(pts[:40], [base_fields[0], field("y", 4, F32, 2)] +
                                 base_fields[2:], 16, xyzi)
    seeds["bad_field_past_point_step"] = cloud(pts[:40], base_fields + [field("t", 12, F64)], 16,
                                               xyzi)
    seeds["bad_unknown_datatype"] = cloud(pts[:40], base_fields + [field("q", 0, 99)], 16, xyzi)
    bad = cloud(pts[:40], base_fields, 16, xyzi)
    bad.is_bigendian = True
    seeds["bad_big_endian"] = bad

    for name, msg in seeds.items():
        with open(os.path.join(a.out, name), "wb") as f:
            f.write(serialize(msg))
    raw = serialize(seeds["valid_unorganised_kitti"])
    extras = {
        "bad_truncated_serialisation": raw[:len(raw) - 37],
        "bad_trailing_bytes": raw + b"\0\1\2",
        "bad_huge_frame_id_length": raw[:12] + struct.pack("<I", 0xFFFFFFF0) + raw[16:],
        "bad_std_msgs_string": serialize(String(data="not a cloud at all")),
        "bad_empty_input": b"",
    }
    for name, data in extras.items():
        with open(os.path.join(a.out, name), "wb") as f:
            f.write(data)
    print("wrote %d seeds to %s" % (len(seeds) + len(extras), a.out))


if __name__ == "__main__":
    main()
