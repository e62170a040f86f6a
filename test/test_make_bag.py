"""scripts/make_bag.py: scan readers (KITTI .bin, PCD ascii/binary/binary_compressed) and the bag
it writes, checked against hand-made inputs and the real files of the data folder
(scripts/gf_data.py: $GF_DATA_DIR, data/, ../shared/data)."""
import os
import shutil
import struct
import subprocess
import sys
import tempfile
import unittest

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.realpath(__file__)))
SCRIPT = os.path.join(ROOT, "scripts", "make_bag.py")
sys.path.insert(0, os.path.join(ROOT, "scripts"))
import make_bag  # noqa: E402
from gf_data import data_dir  # noqa: E402

DATA = data_dir(optional=True) or os.path.join(ROOT, "data")
KITTI = os.path.join(DATA, "semantickitti", "seq00")
OS128 = os.path.join(DATA, "unlabelled", "os128_000000.pcd")  # binary_compressed, organised
# Without the data (a user's own workspace) those tests are skipped with the reason, not passed.
needs_kitti = unittest.skipUnless(os.path.isdir(KITTI), "data not found: " + KITTI)
needs_os128 = unittest.skipUnless(os.path.isfile(OS128), "data not found: " + OS128)


def scan_array(scan):
    """Records of a Scan as a numpy structured array (named fields at their offsets)."""
    np_type = {1: "i1", 2: "u1", 3: "<i2", 4: "<u2", 5: "<i4", 6: "<u4", 7: "<f4", 8: "<f8"}
    dt = np.dtype({"names": [f[0] for f in scan.fields],
                   "formats": [np_type[f[2]] if f[3] == 1 else (np_type[f[2]], f[3])
                               for f in scan.fields],
                   "offsets": [f[1] for f in scan.fields], "itemsize": scan.point_step})
    return np.frombuffer(scan.data, dtype=dt)


def write_pcd(path, names, sizes, types, counts, width, height, body, kind):
    header = ("# .PCD v0.7\nVERSION 0.7\nFIELDS %s\nSIZE %s\nTYPE %s\nCOUNT %s\nWIDTH %d\n"
              "HEIGHT %d\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS %d\nDATA %s\n" % (
                  " ".join(names), " ".join(map(str, sizes)), " ".join(types),
                  " ".join(map(str, counts)), width, height, width * height, kind))
    with open(path, "wb") as f:
        f.write(header.encode("ascii"))
        f.write(body)


class MakeBagTest(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix="gf_make_bag_test_")

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def test_lzf_hand_made_stream(self):
        # 3 literals "abc", then a back reference of length 5 at distance 3 (overlapping copy).
        stream = bytes([2]) + b"abc" + bytes([(5 - 2) << 5, 3 - 1])
        self.assertEqual(make_bag.lzf_decompress(stream, 8), b"abcabcab")
        with self.assertRaises(ValueError):
            make_bag.lzf_decompress(stream, 9)  # header size disagrees with the stream
        with self.assertRaises(ValueError):
            make_bag.lzf_decompress(bytes([0x20, 9]), 3)  # reference before the start

    @needs_kitti
    def test_kitti_bin(self):
        path = os.path.join(KITTI, "000000.bin")
        scan = make_bag.read_scan(path)
        self.assertEqual(scan.width, os.path.getsize(path) // 16)
        self.assertEqual(scan.height, 1)
        self.assertEqual([f[0] for f in scan.fields], ["x", "y", "z", "intensity"])
        raw = np.fromfile(path, dtype="<f4").reshape(-1, 4)
        a = scan_array(scan)
        np.testing.assert_array_equal(a["z"], raw[:, 2])
        np.testing.assert_array_equal(a["intensity"], raw[:, 3])

    @needs_os128
    def test_pcd_binary_compressed_ascii_binary_agree(self):
        """The real binary_compressed file, then 2 of its rows re-written as binary and ascii."""
        scan = make_bag.read_scan(OS128)
        self.assertEqual((scan.width, scan.height), (1875, 128))
        self.assertEqual([f[0] for f in scan.fields],
                         ["x", "y", "z", "timestamp", "intensity", "ring", "azimuth"])
        a = scan_array(scan)
        # Physical sense of the decoded columns (data README: 128 rings, ~34 k points at 0,0,0).
        origin = ((a["x"] == 0) & (a["y"] == 0) & (a["z"] == 0)).reshape(128, 1875)
        self.assertTrue(30000 < int(origin.sum()) < 40000, int(origin.sum()))
        # Every returned point of row r carries ring r (organised layout decoded in order).
        rows = np.broadcast_to(np.arange(128)[:, None], (128, 1875))
        ring = a["ring"].reshape(128, 1875)
        np.testing.assert_array_equal(ring[~origin], rows[~origin])
        self.assertTrue((a["azimuth"] >= 0).all() and (a["azimuth"] < 360).all())

        rows = a[:2 * 1875]
        names = ["x", "y", "z", "timestamp", "intensity", "ring", "azimuth"]
        sizes, types = [4, 4, 4, 8, 1, 2, 4], ["F", "F", "F", "F", "U", "U", "F"]
        packed = np.dtype([(n, t) for n, t in zip(
            names, ["<f4", "<f4", "<f4", "<f8", "u1", "<u2", "<f4"])])
        rec = np.zeros(rows.shape[0], dtype=packed)
        for n in names:
            rec[n] = rows[n]
        bin_path = os.path.join(self.tmp, "rows.pcd")
        write_pcd(bin_path, names, sizes, types, [1] * 7, 1875, 2, rec.tobytes(), "binary")
        lines = []
        for r in rec:
            lines.append("%.9g %.9g %.9g %.17g %d %d %.9g" % tuple(r[n] for n in names))
        ascii_path = os.path.join(self.tmp, "rows_ascii.pcd")
        write_pcd(ascii_path, names, sizes, types, [1] * 7, 1875, 2,
                  ("\n".join(lines) + "\n").encode(), "ascii")
        for path in (bin_path, ascii_path):
            s = make_bag.read_scan(path)
            self.assertEqual((s.width, s.height), (1875, 2), path)
            self.assertEqual(s.fields, scan.fields, path)
            self.assertEqual(s.data, scan.data[:2 * 1875 * scan.point_step], path)

    def test_pcd_padding_count_and_f8_xyz(self):
        """PCL padding "_" stays unnamed bytes, COUNT > 1 is kept, F8 x/y/z become float32."""
        names, sizes, types, counts = ["x", "y", "z", "_", "rgb3"], [8, 8, 8, 1, 1], \
            ["F", "F", "F", "U", "U"], [1, 1, 1, 2, 3]
        body = b""
        for i in range(3):
            body += struct.pack("<ddd", i + 0.5, -i, 2.0 * i) + b"\0\0" + bytes([i, i + 1, i + 2])
        path = os.path.join(self.tmp, "pad.pcd")
        write_pcd(path, names, sizes, types, counts, 3, 1, body, "binary")
        s = make_bag.read_scan(path)
        self.assertEqual(s.fields, [("x", 0, 7, 1), ("y", 4, 7, 1), ("z", 8, 7, 1),
                                    ("rgb3", 14, 2, 3)])
        self.assertEqual(s.point_step, 17)
        a = scan_array(s)
        np.testing.assert_array_equal(a["x"], np.float32([0.5, 1.5, 2.5]))
        np.testing.assert_array_equal(a["rgb3"][2], [2, 3, 4])

    def test_bad_scans_refused(self):
        cases = {
            "no_z.pcd": (["x", "y"], [4, 4], ["F", "F"], [1, 1], b"\0" * 16, "binary"),
            "short.pcd": (["x", "y", "z"], [4, 4, 4], ["F", "F", "F"], [1, 1, 1], b"\0" * 20,
                          "binary"),
            "int64.pcd": (["x", "y", "z", "t"], [4, 4, 4, 8], ["F", "F", "F", "U"],
                          [1, 1, 1, 1], b"\0" * 40, "binary"),
            "lzf.pcd": (["x", "y", "z"], [4, 4, 4], ["F", "F", "F"], [1, 1, 1],
                        struct.pack("<II", 2, 24) + b"\x05\x00", "binary_compressed"),
        }
        for fname, (names, sizes, types, counts, body, kind) in cases.items():
            path = os.path.join(self.tmp, fname)
            write_pcd(path, names, sizes, types, counts, 2, 1, body, kind)
            with self.assertRaises(make_bag.ScanError, msg=fname) as ctx:
                make_bag.read_scan(path)
            self.assertIn(fname, str(ctx.exception))
        odd = os.path.join(self.tmp, "odd.bin")
        with open(odd, "wb") as f:
            f.write(b"\0" * 20)
        with self.assertRaises(make_bag.ScanError):
            make_bag.read_scan(odd)

    @needs_kitti
    def test_cli_writes_bag(self):
        import rosbag
        out = os.path.join(self.tmp, "cli.bag")
        kitti = [os.path.join(KITTI, "00000%d.bin" % i) for i in (0, 1)]
        p = subprocess.run([sys.executable, SCRIPT, "-q", "-o", out, "--rate", "4",
                            "--frame-id", "os_sensor", "--topic", "/cloud", "--start", "100",
                            "--loops", "2"] + kitti, stdout=subprocess.PIPE,
                           stderr=subprocess.STDOUT, universal_newlines=True)
        self.assertEqual(p.returncode, 0, p.stdout)
        with rosbag.Bag(out) as bag:
            msgs = list(bag.read_messages())
        self.assertEqual(len(msgs), 4)
        self.assertEqual({m.topic for m in msgs}, {"/cloud"})
        self.assertEqual([m.message.header.stamp.to_sec() for m in msgs],
                         [100.0, 100.25, 100.5, 100.75])
        self.assertEqual([m.timestamp for m in msgs], [m.message.header.stamp for m in msgs])
        self.assertEqual([m.message.header.seq for m in msgs], [0, 1, 2, 3])
        for m, f in zip(msgs, kitti + kitti):
            cloud = m.message
            self.assertEqual(cloud.header.frame_id, "os_sensor")
            self.assertEqual(cloud.width * 16, os.path.getsize(f))
            self.assertEqual(cloud.row_step, cloud.width * cloud.point_step)
            with open(f, "rb") as fh:
                self.assertEqual(bytes(cloud.data), fh.read())

    def test_cli_errors(self):
        out = os.path.join(self.tmp, "never.bag")
        for args in (["/nonexistent/dir"], ["--rate", "0", KITTI], [self.tmp + "/none.pcd"]):
            p = subprocess.run([sys.executable, SCRIPT, "-o", out] + args,
                               stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
            self.assertNotEqual(p.returncode, 0, args)
            self.assertFalse(os.path.exists(out), args)


if __name__ == "__main__":
    unittest.main()
