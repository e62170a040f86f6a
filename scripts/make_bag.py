#!/usr/bin/env python3
"""Writes a rosbag of sensor_msgs/PointCloud2 from a sequence of scan files.

Inputs (files or directories, taken in the order given; a directory contributes its scan files
sorted by name):
  *.bin  KITTI velodyne scans: float32 x y z intensity records -> fields x y z intensity.
  *.pcd  PCD v0.7/v0.6, DATA ascii, binary or binary_compressed (LZF): every field of the file is
         kept (name, type, count; PCL padding fields "_" stay as unnamed bytes), organised clouds
         keep width x height. x/y/z stored as F8 are converted to float32 (the nodelets need
         float32 x/y/z); 64-bit integer fields (I8/U8) have no PointField type and are refused.

Every message gets frame_id, stamp = start + i / rate (strictly increasing), seq = i, and is
written at bag time = its stamp, so `rosbag play --clock` replays it at the given rate.

Example:
  scripts/make_bag.py -o /tmp/seq00.bag --rate 10 --frame-id velodyne --topic /points_raw \\
      data/semantickitti/seq00   # bash scripts/get_data.sh
"""
import argparse
import os
import struct
import sys

import numpy as np

SCAN_EXTENSIONS = (".bin", ".pcd")

# PCD TYPE+SIZE -> (numpy dtype, sensor_msgs/PointField datatype)
_PCD_TYPES = {
    ("I", 1): ("<i1", 1), ("U", 1): ("<u1", 2),
    ("I", 2): ("<i2", 3), ("U", 2): ("<u2", 4),
    ("I", 4): ("<i4", 5), ("U", 4): ("<u4", 6),
    ("F", 4): ("<f4", 7), ("F", 8): ("<f8", 8),
}


class ScanError(Exception):
    """A scan file that cannot be read (the message names the file and the reason)."""


class Scan:
    """One scan as packed little-endian records plus the PointField layout describing them."""

    def __init__(self, data, fields, point_step, width, height, is_dense):
        self.data = data              # bytes, height * width * point_step
        self.fields = fields          # [(name, offset, datatype, count)]
        self.point_step = point_step  # bytes per record
        self.width = width
        self.height = height
        self.is_dense = is_dense      # no NaN/Inf in x/y/z


# ------------------------------------------------------------------------------------ KITTI .bin

def read_kitti_bin(path):
    raw = np.fromfile(path, dtype="<f4")
    if raw.size % 4:
        raise ScanError("%s: size %d bytes is not a multiple of 16 (x y z intensity float32)"
                        % (path, raw.size * 4))
    pts = raw.reshape(-1, 4)
    fields = [("x", 0, 7, 1), ("y", 4, 7, 1), ("z", 8, 7, 1), ("intensity", 12, 7, 1)]
    dense = bool(np.isfinite(pts[:, :3]).all())
    return Scan(pts.tobytes(), fields, 16, pts.shape[0], 1, dense)


# ------------------------------------------------------------------------------------ PCD

def lzf_decompress(src, out_len):
    """liblzf decompression (the codec of PCD binary_compressed)."""
    out = bytearray(out_len)
    ip = op = 0
    n = len(src)
    while ip < n:
        ctrl = src[ip]
        ip += 1
        if ctrl < 32:  # literal run of ctrl + 1 bytes
            length = ctrl + 1
            if ip + length > n or op + length > out_len:
                raise ValueError("LZF literal run past the end")
            out[op:op + length] = src[ip:ip + length]
            ip += length
            op += length
        else:  # back reference
            length = ctrl >> 5
            if length == 7:
                if ip >= n:
                    raise ValueError("LZF truncated length")
                length += src[ip]
                ip += 1
            if ip >= n:
                raise ValueError("LZF truncated offset")
            ref = op - ((ctrl & 0x1F) << 8) - src[ip] - 1
            ip += 1
            length += 2
            if ref < 0 or op + length > out_len:
                raise ValueError("LZF back reference out of range")
            dist = op - ref
            if dist >= length:
                out[op:op + length] = out[ref:ref + length]
            else:  # overlapping copy repeats the last `dist` bytes
                chunk = bytes(out[ref:op])
                reps = chunk * (length // dist + 1)
                out[op:op + length] = reps[:length]
            op += length
    if op != out_len:
        raise ValueError("LZF output %d bytes, header says %d" % (op, out_len))
    return bytes(out)


def _parse_pcd_header(f, path):
    header = {}
    order = ("VERSION", "FIELDS", "SIZE", "TYPE", "COUNT", "WIDTH", "HEIGHT", "VIEWPOINT",
             "POINTS", "DATA")
    while True:
        line = f.readline()
        if not line:
            raise ScanError("%s: PCD header ends before DATA" % path)
        text = line.decode("ascii", "replace").strip()
        if not text or text.startswith("#"):
            continue
        key, _, rest = text.partition(" ")
        key = key.upper()
        if key not in order:
            raise ScanError("%s: unknown PCD header line %r" % (path, text))
        header[key] = rest.split()
        if key == "DATA":
            return header


def read_pcd(path):
    with open(path, "rb") as f:
        header = _parse_pcd_header(f, path)
        body = f.read()
    try:
        names = header["FIELDS"]
        sizes = [int(s) for s in header["SIZE"]]
        types = [t.upper() for t in header["TYPE"]]
        counts = [int(c) for c in header.get("COUNT", ["1"] * len(names))]
        width = int(header["WIDTH"][0])
        height = int(header.get("HEIGHT", ["1"])[0])
        points = int(header.get("POINTS", [str(width * height)])[0])
        data_kind = header["DATA"][0].lower()
    except (KeyError, IndexError, ValueError) as e:
        raise ScanError("%s: bad PCD header (%s)" % (path, e))
    if not (len(names) == len(sizes) == len(types) == len(counts)):
        raise ScanError("%s: FIELDS/SIZE/TYPE/COUNT lengths differ" % path)
    if points != width * height:
        raise ScanError("%s: POINTS %d != WIDTH %d * HEIGHT %d" % (path, points, width, height))
    for axis in ("x", "y", "z"):
        if axis not in names:
            raise ScanError("%s: no field '%s' (fields: %s)" % (path, axis, " ".join(names)))

    # File record layout (packed, in FIELDS order).
    file_fields = []
    for name, size, typ, count in zip(names, sizes, types, counts):
        key = (typ, size)
        if key not in _PCD_TYPES:
            raise ScanError("%s: field '%s' has TYPE %s SIZE %d, which PointCloud2 cannot hold"
                            % (path, name, typ, size))
        file_fields.append((name, _PCD_TYPES[key][0], count))
    file_dtype = np.dtype([("f%d" % i, dt, (c,)) for i, (_, dt, c) in enumerate(file_fields)])

    if data_kind == "binary":
        need = points * file_dtype.itemsize
        if len(body) < need:
            raise ScanError("%s: binary data has %d bytes, need %d" % (path, len(body), need))
        rec = np.frombuffer(body[:need], dtype=file_dtype)
    elif data_kind == "binary_compressed":
        if len(body) < 8:
            raise ScanError("%s: binary_compressed data shorter than its 8-byte header" % path)
        csize, usize = struct.unpack("<II", body[:8])
        if usize != points * file_dtype.itemsize:
            raise ScanError("%s: binary_compressed uncompressed size %d != %d points * %d bytes"
                            % (path, usize, points, file_dtype.itemsize))
        try:
            raw = lzf_decompress(body[8:8 + csize], usize) if points else b""
        except ValueError as e:
            raise ScanError("%s: corrupt binary_compressed data (%s)" % (path, e))
        # Stored field by field (all x, then all y, ...): gather into records.
        rec = np.zeros(points, dtype=file_dtype)
        pos = 0
        for i, (_, dt, c) in enumerate(file_fields):
            nbytes = points * np.dtype(dt).itemsize * c
            rec["f%d" % i] = np.frombuffer(raw[pos:pos + nbytes], dtype=dt).reshape(points, c)
            pos += nbytes
    elif data_kind == "ascii":
        tokens = body.decode("ascii", "replace").split()
        per_point = sum(counts)
        if len(tokens) < points * per_point:
            raise ScanError("%s: ascii data has %d values, need %d"
                            % (path, len(tokens), points * per_point))
        table = np.array(tokens[:points * per_point], dtype=object).reshape(points, per_point)
        rec = np.zeros(points, dtype=file_dtype)
        col = 0
        for i, (_, dt, c) in enumerate(file_fields):
            block = table[:, col:col + c]
            try:
                if np.dtype(dt).kind == "f":
                    vals = block.astype(np.float64)
                else:
                    vals = np.vectorize(lambda s: int(float(s)))(block) if block.size else block
            except ValueError as e:
                raise ScanError("%s: bad ascii value in field '%s' (%s)" % (path, names[i], e))
            rec["f%d" % i] = np.asarray(vals).astype(dt).reshape(points, c)
            col += c
    else:
        raise ScanError("%s: DATA %s is not supported (ascii, binary, binary_compressed)"
                        % (path, data_kind))

    # Output records: the file's fields in order; x/y/z forced to float32; "_" kept as padding.
    out_fields, out_dtype_spec, offset = [], [], 0
    for i, ((name, dt, c), size) in enumerate(zip(file_fields, sizes)):
        if name in ("x", "y", "z") and (dt != "<f4" or c != 1):
            if c != 1:
                raise ScanError("%s: field '%s' has COUNT %d, expected 1" % (path, name, c))
            dt = "<f4"
        out_dtype_spec.append(("f%d" % i, dt, (c,)))
        if name != "_":
            out_fields.append((name, offset, _PCD_TYPES[(dt[1].upper(), np.dtype(dt).itemsize)][1],
                               c))
        offset += np.dtype(dt).itemsize * c
    out_dtype = np.dtype(out_dtype_spec)
    out = np.zeros(points, dtype=out_dtype)
    for i in range(len(file_fields)):
        out["f%d" % i] = rec["f%d" % i]
    xyz = np.stack([out["f%d" % names.index(a)][:, 0] for a in ("x", "y", "z")], axis=1)
    dense = bool(np.isfinite(xyz).all())
    return Scan(out.tobytes(), out_fields, out_dtype.itemsize, width, height, dense)


def read_scan(path):
    ext = os.path.splitext(path)[1].lower()
    if ext == ".bin":
        return read_kitti_bin(path)
    if ext == ".pcd":
        return read_pcd(path)
    raise ScanError("%s: unknown scan type (expected %s)" % (path, ", ".join(SCAN_EXTENSIONS)))


def expand_inputs(paths):
    """Files in the order given; a directory gives its .bin/.pcd files sorted by name."""
    files = []
    for p in paths:
        if os.path.isdir(p):
            found = sorted(os.path.join(p, n) for n in os.listdir(p)
                           if n.lower().endswith(SCAN_EXTENSIONS))
            if not found:
                raise ScanError("%s: no .bin or .pcd files in this directory" % p)
            files.extend(found)
        elif os.path.isfile(p):
            files.append(p)
        else:
            raise ScanError("%s: no such file or directory" % p)
    return files


# ------------------------------------------------------------------------------------ bag

def to_message(scan, frame_id, stamp, seq):
    from sensor_msgs.msg import PointCloud2, PointField
    msg = PointCloud2()
    msg.header.seq = seq
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.height = scan.height
    msg.width = scan.width
    msg.fields = [PointField(name=n, offset=o, datatype=d, count=c) for n, o, d, c in scan.fields]
    msg.is_bigendian = False
    msg.point_step = scan.point_step
    msg.row_step = scan.width * scan.point_step
    msg.data = scan.data
    msg.is_dense = scan.is_dense
    return msg


def write_bag(files, output, topic, frame_id, rate, start, first=0, count=0, loops=1,
              log=print):
    """Writes the bag; returns the number of messages written."""
    import rosbag
    import rospy
    selected = files[first:]
    if count:
        selected = selected[:count]
    if not selected:
        raise ScanError("no scan files selected (first=%d count=%d of %d)"
                        % (first, count, len(files)))
    # Read every file before the bag is opened: a bad file leaves no half-written bag.
    scans = [(f, read_scan(f)) for f in selected]
    n = 0
    with rosbag.Bag(output, "w") as bag:
        for _ in range(loops):
            for path, scan in scans:
                stamp = rospy.Time.from_sec(start) + rospy.Duration.from_sec(n / rate)
                bag.write(topic, to_message(scan, frame_id, stamp, n), stamp)
                log("%s -> %s #%d stamp %.3f: %d x %d points, %d fields"
                    % (os.path.basename(path), topic, n, stamp.to_sec(), scan.width, scan.height,
                       len(scan.fields)))
                n += 1
    return n


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog=__doc__.split("\n", 2)[2])
    ap.add_argument("paths", nargs="+", help="scan files or directories (.bin, .pcd)")
    ap.add_argument("-o", "--output", required=True, help="bag file to write")
    ap.add_argument("--topic", default="/points_raw", help="topic (default /points_raw)")
    ap.add_argument("--frame-id", default="velodyne", help="header frame_id (default velodyne)")
    ap.add_argument("--rate", type=float, default=10.0, help="scans per second (default 10)")
    ap.add_argument("--start", type=float, default=1.0,
                    help="stamp of the first scan [s since epoch] (default 1.0)")
    ap.add_argument("--first", type=int, default=0, help="skip this many files first")
    ap.add_argument("--count", type=int, default=0, help="use at most this many files (0 = all)")
    ap.add_argument("--loops", type=int, default=1,
                    help="write the sequence this many times (stamps keep increasing)")
    ap.add_argument("-q", "--quiet", action="store_true", help="no per-message line")
    a = ap.parse_args(argv)
    if not (a.rate > 0):
        ap.error("--rate must be > 0")
    if a.start <= 0:
        ap.error("--start must be > 0 (a zero stamp means 'no time' in ROS)")
    if a.first < 0 or a.count < 0 or a.loops < 1:
        ap.error("--first and --count must be >= 0, --loops >= 1")
    try:
        files = expand_inputs(a.paths)
        n = write_bag(files, a.output, a.topic, a.frame_id, a.rate, a.start, a.first, a.count,
                      a.loops, log=(lambda s: None) if a.quiet else print)
    except ScanError as e:
        print("make_bag.py: error: %s" % e, file=sys.stderr)
        return 1
    print("wrote %d messages on %s to %s" % (n, a.topic, a.output))
    return 0


if __name__ == "__main__":
    sys.exit(main())
