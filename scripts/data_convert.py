#!/usr/bin/env python3
"""Conversions of scripts/get_data.sh: public source files -> the labelled scans of the data folder.

  data_convert.py isprs SAMP-utm.pcd SAMP-utm-ground.pcd OUT.pcd
      ISPRS filter test tile (PointCloudLibrary/data terrain/): x y z label, label 1 where the point
      is also in the reference ground cloud, else 0; x and y minus the tile's minimum rounded
      down to the metre.
  data_convert.py rellis SCAN.bin SCAN.label OUT.pcd
      RELLIS-3D Ouster frame (KITTI .bin + RELLIS class ids): no-return (0,0,0) cells dropped,
      x y z intensity label with 1 ground / 0 non-ground / 255 ignored (RELLIS_* below).
  data_convert.py las IN.laz OUT.pcd --offset X Y [--ignore C ...]
      airborne tile with the provider's classes: x y z intensity label, label 1 for LAS class 2,
      255 for the --ignore classes, else 0; x, y minus the offset. An uncompressed LAS needs
      numpy only; a LAZ needs laspy with a LAZ backend (lazrs or laszip) or PDAL's command-line
      tool: Debian 12 packages none of them.

Output: binary PCD, written to OUT.pcd.part and renamed only when complete. numpy only (plus
the LAZ reader for `las`). Python 3.8+.
"""
import argparse
import os
import shutil
import subprocess
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import make_bag  # noqa: E402 (the PCD LZF decoder; numpy only)

# RELLIS-3D ontology ids -> ground protocol of the data README (offroad/).
RELLIS_GROUND = (1, 3, 10, 23, 31, 33)  # dirt, grass, asphalt, concrete, puddle, mud
RELLIS_NONGROUND = (4, 5, 8, 9, 12, 15, 17, 18, 19, 27)  # tree, pole, vehicle, object, building,
#                                                         log, person, fence, bush, barrier
# everything else (void 0, water 6, sky 7, rubble 34, ...) is ignored: 255


class ConvertError(Exception):
    pass


def lzf_decompress(data, out_len):
    """LZF (liblzf) decompression, as PCD's binary_compressed uses it: make_bag.py's decoder,
    its errors as ConvertError."""
    try:
        return make_bag.lzf_decompress(data, out_len)
    except ValueError as e:
        raise ConvertError("corrupt LZF data: %s" % e)


def read_pcd(path):
    """Fields of a PCD (ascii, binary or binary_compressed) as {name: array}, in file order."""
    with open(path, "rb") as f:
        raw = f.read()
    header = {}
    pos = 0
    while True:
        end = raw.find(b"\n", pos)
        if end < 0:
            raise ConvertError("%s: no DATA line in the PCD header" % path)
        line = raw[pos:end].decode("ascii", "replace").strip()
        pos = end + 1
        if not line or line.startswith("#"):
            continue
        key, _, value = line.partition(" ")
        header[key.upper()] = value.split()
        if key.upper() == "DATA":
            break
    try:
        names = header["FIELDS"]
        sizes = [int(s) for s in header["SIZE"]]
        types = header["TYPE"]
        counts = [int(c) for c in header.get("COUNT", ["1"] * len(names))]
        npts = int(header["POINTS"][0])
        kind = header["DATA"][0]
    except (KeyError, ValueError, IndexError) as e:
        raise ConvertError("%s: bad PCD header (%s)" % (path, e))
    dts = [np.dtype("<%s%d" % ({"F": "f", "I": "i", "U": "u"}[t], s)) for t, s in zip(types, sizes)]
    if kind == "ascii":
        vals = np.loadtxt(raw[pos:].decode("ascii").splitlines(), ndmin=2)
        cols, fields = 0, {}
        for nm, dt, c in zip(names, dts, counts):
            fields[nm] = vals[:, cols].astype(dt)
            cols += c
        return fields
    if kind == "binary":
        rec = np.dtype([(nm + "_%d" % i, dt, (c,)) for i, (nm, dt, c) in
                        enumerate(zip(names, dts, counts))])
        arr = np.frombuffer(raw, dtype=rec, count=npts, offset=pos)
        return {nm: arr[nm + "_%d" % i][:, 0] for i, nm in enumerate(names)}
    if kind == "binary_compressed":
        csize, usize = np.frombuffer(raw, dtype="<u4", count=2, offset=pos)
        body = lzf_decompress(raw[pos + 8:pos + 8 + int(csize)], int(usize))
        fields, off = {}, 0
        for nm, dt, c in zip(names, dts, counts):  # column-major: one field after another
            fields[nm] = np.frombuffer(body, dtype=dt, count=npts * c, offset=off)[::c]
            off += npts * c * dt.itemsize
        return fields
    raise ConvertError("%s: unknown PCD DATA kind %r" % (path, kind))


def write_pcd(path, columns):
    """Binary PCD of (name, array) columns (float32 'F' or uint32 'U'); atomic (.part, rename)."""
    n = len(columns[0][1])
    names = [c[0] for c in columns]
    types = ["U" if c[1].dtype.kind == "u" else "F" for c in columns]
    header = ("# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS %s\nSIZE %s\n"
              "TYPE %s\nCOUNT %s\nWIDTH %d\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS %d\n"
              "DATA binary\n" % (" ".join(names), " ".join(["4"] * len(names)), " ".join(types),
                                 " ".join(["1"] * len(names)), n, n))
    rec = np.zeros(n, dtype=[(nm, "<u4" if t == "U" else "<f4") for nm, t in zip(names, types)])
    for nm, arr in columns:
        rec[nm] = arr
    tmp = path + ".part"
    try:
        with open(tmp, "wb") as f:
            f.write(header.encode("ascii"))
            f.write(rec.tobytes())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def convert_isprs(utm, ground, out):
    full, gnd = read_pcd(utm), read_pcd(ground)
    xyz = np.stack([full["x"], full["y"], full["z"]], axis=1).astype(np.float32)
    gxyz = np.stack([gnd["x"], gnd["y"], gnd["z"]], axis=1).astype(np.float32)
    # A point is ground when the reference ground cloud has the same float32 x y z.
    key = np.ascontiguousarray(xyz).view("V12").ravel()
    gkey = np.ascontiguousarray(gxyz).view("V12").ravel()
    label = np.isin(key, gkey).astype(np.uint32)
    if label.sum() == 0:
        raise ConvertError("%s: no point of %s matches: not the tile's ground cloud" %
                           (utm, ground))
    ox, oy = tile_offset(xyz)
    columns = [("x", (xyz[:, 0].astype(np.float64) - ox).astype(np.float32)),
               ("y", (xyz[:, 1].astype(np.float64) - oy).astype(np.float32)),
               ("z", xyz[:, 2]), ("label", label)]
    write_pcd(out, columns)


def tile_offset(xyz):
    """The tile's offset: its minimum x and y rounded down to the metre."""
    return float(np.floor(xyz[:, 0].min())), float(np.floor(xyz[:, 1].min()))


def convert_rellis(scan, labels, out):
    pts = np.fromfile(scan, dtype="<f4")
    lab = np.fromfile(labels, dtype="<u4")
    if pts.size % 4 or pts.size // 4 != lab.size:
        raise ConvertError("%s (%d values) and %s (%d labels) do not match: 4 floats a point" %
                           (scan, pts.size, labels, lab.size))
    pts = pts.reshape(-1, 4)
    keep = ~((pts[:, 0] == 0) & (pts[:, 1] == 0) & (pts[:, 2] == 0))
    cls = lab[keep] & 0xFFFF
    out_lab = np.full(cls.shape, 255, dtype=np.uint32)
    out_lab[np.isin(cls, RELLIS_GROUND)] = 1
    out_lab[np.isin(cls, RELLIS_NONGROUND)] = 0
    p = pts[keep]
    write_pcd(out, [("x", p[:, 0]), ("y", p[:, 1]), ("z", p[:, 2]), ("intensity", p[:, 3]),
                    ("label", out_lab)])


def read_plain_las(path):
    """x y z (float64), intensity, classification of an uncompressed LAS file (1.0-1.4, point
    formats 0-10), numpy only; None for anything else (LAZ)."""
    with open(path, "rb") as f:
        b = f.read()
    if len(b) < 227 or b[:4] != b"LASF":
        return None
    fmt = b[104]
    if fmt & 0xC0:  # LAZ marks compressed points with bit 7 (or 6) of the format id
        return None
    if fmt > 10:
        raise ConvertError("%s: LAS point format %d is not one of 0-10" % (path, fmt))
    offset = int(np.frombuffer(b, "<u4", 1, 96)[0])
    rec = int(np.frombuffer(b, "<u2", 1, 105)[0])
    n = int(np.frombuffer(b, "<u4", 1, 107)[0])
    if n == 0 and b[25] >= 4 and len(b) >= 255:  # LAS 1.4: the 64-bit count
        n = int(np.frombuffer(b, "<u8", 1, 247)[0])
    if offset + n * rec > len(b):
        raise ConvertError("%s: %d points of %d bytes do not fit in the file" % (path, n, rec))
    scale = np.frombuffer(b, "<f8", 3, 131)
    origin = np.frombuffer(b, "<f8", 3, 155)
    pts = np.frombuffer(b, np.uint8, n * rec, offset).reshape(n, rec)
    xyz = [pts[:, 4 * i:4 * i + 4].copy().view("<i4").ravel() * scale[i] + origin[i]
           for i in range(3)]
    intensity = pts[:, 12:14].copy().view("<u2").ravel()
    # Formats 0-5: 5 bits of class in byte 15; 6-10: a whole byte at 16.
    cls = (pts[:, 15] & 0x1F) if fmt < 6 else pts[:, 16]
    return xyz[0], xyz[1], xyz[2], intensity, cls.astype(np.int64)


def read_las(path):
    """x y z (float64), intensity, classification of a LAS/LAZ file: an uncompressed LAS by
    read_plain_las(), a LAZ by laspy, else by PDAL's CLI."""
    plain = read_plain_las(path)
    if plain is not None:
        return plain
    try:
        import laspy  # noqa: F401 (optional)
        las = laspy.read(path)
        return (np.asarray(las.x), np.asarray(las.y), np.asarray(las.z),
                np.asarray(las.intensity), np.asarray(las.classification))
    except ImportError:
        pass
    except Exception as e:  # laspy without a LAZ backend says so here
        raise ConvertError("%s: laspy cannot read it (%s): install a LAZ backend "
                           "(pip install 'laspy[lazrs]') or PDAL" % (path, e))
    pdal = shutil.which("pdal")
    if not pdal:
        raise ConvertError("%s: reading LAZ needs laspy with lazrs/laszip (pip install "
                           "'laspy[lazrs]') or PDAL's 'pdal' command; Debian 12 packages neither. "
                           "Or take a copy of the data: get_data.sh --from DIR" % path)
    tmpdir = tempfile.mkdtemp()
    try:
        txt = os.path.join(tmpdir, "points.txt")
        subprocess.run([pdal, "translate", path, txt, "--writers.text.order=X,Y,Z,Intensity,"
                        "Classification", "--writers.text.keep_unspecified=false",
                        "--writers.text.precision=8"], check=True)
        v = np.loadtxt(txt, delimiter=",", skiprows=1, ndmin=2)
    finally:
        shutil.rmtree(tmpdir)
    return v[:, 0], v[:, 1], v[:, 2], v[:, 3], v[:, 4].astype(np.int64)


def convert_las(laz, out, offset, ignore):
    x, y, z, intensity, cls = read_las(laz)
    label = np.where(cls == 2, 1, 0).astype(np.uint32)
    label[np.isin(cls, ignore)] = 255
    write_pcd(out, [("x", (x - offset[0]).astype(np.float32)),
                    ("y", (y - offset[1]).astype(np.float32)), ("z", z.astype(np.float32)),
                    ("intensity", intensity.astype(np.float32)), ("label", label)])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="kind", required=True)
    p = sub.add_parser("isprs")
    p.add_argument("utm")
    p.add_argument("ground")
    p.add_argument("out")
    p = sub.add_parser("rellis")
    p.add_argument("scan")
    p.add_argument("labels")
    p.add_argument("out")
    p = sub.add_parser("las")
    p.add_argument("laz")
    p.add_argument("out")
    p.add_argument("--offset", nargs=2, type=float, default=(0.0, 0.0))
    p.add_argument("--ignore", nargs="*", type=int, default=[])
    a = ap.parse_args(argv)
    try:
        if a.kind == "isprs":
            convert_isprs(a.utm, a.ground, a.out)
        elif a.kind == "rellis":
            convert_rellis(a.scan, a.labels, a.out)
        else:
            convert_las(a.laz, a.out, a.offset, a.ignore)
    except (ConvertError, OSError, subprocess.CalledProcessError) as e:
        print("data_convert.py: %s" % e, file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
