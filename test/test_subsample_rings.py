"""scripts/subsample_rings.py: the rings it finds and keeps in a synthetic KITTI scan whose ring of
every point is known, labels kept aligned with their points, bad input refused."""
import array
import math
import os
import shutil
import subprocess
import sys
import tempfile
import unittest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCRIPT = os.path.join(ROOT, "scripts", "subsample_rings.py")


def write_scan(path, rings, per_ring=360, short_run_ring=None):
    """KITTI records laser by laser, each ring one sweep from -pi to +pi (as the HDL-64E's
    file order); the label of a point is its ring. short_run_ring: that ring first repeats a
    tiny sweep of 10 points (a run the script must not count as a ring)."""
    pts, labs = array.array("f"), array.array("I")
    for r in range(rings):
        sweeps = [10, per_ring] if r == short_run_ring else [per_ring]
        for count in sweeps:
            for i in range(count):
                az = -math.pi + (i + 0.5) * 2 * math.pi / count
                pts.extend([10 * math.cos(az), 10 * math.sin(az), -1.0 - 0.1 * r, float(r)])
                labs.append(r)
    with open(path + ".bin", "wb") as f:
        f.write(pts.tobytes())
    with open(path + ".label", "wb") as f:
        f.write(labs.tobytes())


def read(path, code):
    a = array.array(code)
    with open(path, "rb") as f:
        a.frombytes(f.read())
    return a


class SubsampleRingsTest(unittest.TestCase):

    def setUp(self):
        self.dir = tempfile.mkdtemp()

    def tearDown(self):
        shutil.rmtree(self.dir)

    def run_script(self, *args):
        return subprocess.run([sys.executable, SCRIPT] + list(args), stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, universal_newlines=True)

    def test_keeps_every_nth_ring_with_its_labels(self):
        src = os.path.join(self.dir, "000000")
        write_scan(src, rings=16, short_run_ring=5)
        for every, want in ((4, [0, 4, 8, 12]), (2, list(range(0, 16, 2))), (1, list(range(16)))):
            out = os.path.join(self.dir, "out%d" % every)
            res = self.run_script(str(every), out, src + ".bin")
            self.assertEqual(res.returncode, 0, res.stderr)
            self.assertIn("16 rings", res.stdout)
            pts = read(os.path.join(out, "000000.bin"), "f")
            labs = read(os.path.join(out, "000000.label"), "I")
            self.assertEqual(len(pts), 4 * len(labs))
            self.assertEqual(sorted(set(labs)), want)
            # each kept point is still beside its own label (intensity was set to the ring)
            self.assertTrue(all(pts[4 * i + 3] == labs[i] for i in range(len(labs))))
            self.assertEqual(len(labs), 360 * len(want) + (10 if 5 in want else 0))

    def test_fov_keeps_the_forward_sector(self):
        src = os.path.join(self.dir, "f")
        write_scan(src, rings=4)
        out = os.path.join(self.dir, "fov")
        res = self.run_script("--fov", "90", "1", out, src + ".bin")
        self.assertEqual(res.returncode, 0, res.stderr)
        pts = read(os.path.join(out, "f.bin"), "f")
        az = [math.degrees(math.atan2(pts[4 * i + 1], pts[4 * i])) for i in range(len(pts) // 4)]
        self.assertEqual(len(az), 4 * 90)  # a quarter of each 360-point ring
        self.assertLessEqual(max(abs(a) for a in az), 45.0)
        self.assertEqual(self.run_script("--fov", "0", "1", out, src + ".bin").returncode, 2)

    def test_scan_without_labels_and_bad_input(self):
        src = os.path.join(self.dir, "a")
        write_scan(src, rings=8)
        os.remove(src + ".label")
        out = os.path.join(self.dir, "o")
        self.assertEqual(self.run_script("4", out, src + ".bin").returncode, 0)
        self.assertEqual(len(read(os.path.join(out, "a.bin"), "f")), 4 * 2 * 360)
        self.assertFalse(os.path.exists(os.path.join(out, "a.label")))
        with open(os.path.join(self.dir, "bad.bin"), "wb") as f:
            f.write(b"\0" * 17)
        res = self.run_script("4", out, os.path.join(self.dir, "bad.bin"))
        self.assertEqual(res.returncode, 1)
        self.assertIn("not KITTI", res.stderr)
        write_scan(os.path.join(self.dir, "b"), rings=2)
        with open(os.path.join(self.dir, "b.label"), "ab") as f:
            f.write(b"\0\0\0\0")
        res = self.run_script("2", out, os.path.join(self.dir, "b.bin"))
        self.assertEqual(res.returncode, 1)
        self.assertIn("labels for", res.stderr)
        self.assertEqual(self.run_script("0", out, src + ".bin").returncode, 2)


if __name__ == "__main__":
    unittest.main()
