"""scripts/derive_scans.py: voxel and random downsampling keep each kept point beside its own
label, a crop box keeps (and a cut box drops) exactly the points inside it, a shift and a tilt
move the points exactly and keep SemanticKITTI's vegetation truth, bad input is refused."""
import array
import math
import os
import shutil
import subprocess
import sys
import tempfile
import unittest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCRIPT = os.path.join(ROOT, "scripts", "derive_scans.py")


def write_scan(path, pts, labs):
    with open(path + ".bin", "wb") as f:
        f.write(array.array("f", pts).tobytes())
    with open(path + ".label", "wb") as f:
        f.write(array.array("I", labs).tobytes())


def read(path, code):
    a = array.array(code)
    with open(path, "rb") as f:
        a.frombytes(f.read())
    return a


class DeriveScansTest(unittest.TestCase):

    def setUp(self):
        self.dir = tempfile.mkdtemp()
        # a 10 x 10 grid of points 0.1 m apart, two to a spot (the second 1 cm higher); the
        # intensity is the point's index, its label 40 "road" with the index as instance id
        pts, labs = [], []
        for i in range(200):
            cell = i // 2
            pts += [0.1 * (cell % 10) + 0.05, 0.1 * (cell // 10) + 0.05, -1.75 + 0.01 * (i % 2), i]
            labs.append((i << 16) | 40)
        self.src = os.path.join(self.dir, "000000")
        write_scan(self.src, pts, labs)

    def tearDown(self):
        shutil.rmtree(self.dir)

    def run_script(self, *args):
        return subprocess.run([sys.executable, SCRIPT] + list(args), stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, universal_newlines=True)

    def derived(self, *args):
        out = os.path.join(self.dir, "out")
        res = self.run_script(*(list(args) + [out, self.src + ".bin"]))
        self.assertEqual(res.returncode, 0, res.stderr)
        return read(os.path.join(out, "000000.bin"), "f"), read(os.path.join(out, "000000.label"),
                                                                "I")

    def test_voxel_keeps_the_first_point_of_each_cube(self):
        pts, labs = self.derived("--voxel", "0.1")
        self.assertEqual(len(labs), 100)  # one of each pair
        self.assertEqual([int(pts[4 * i + 3]) for i in range(100)], list(range(0, 200, 2)))
        self.assertTrue(all(labs[i] >> 16 == int(pts[4 * i + 3]) for i in range(100)))
        pts, labs = self.derived("--voxel", "0.2")
        self.assertEqual(len(labs), 25)

    def test_keep_a_random_share_in_input_order(self):
        pts, labs = self.derived("--keep", "0.25", "--seed", "3")
        idx = [int(pts[4 * i + 3]) for i in range(len(labs))]
        self.assertEqual(len(idx), 50)
        self.assertEqual(idx, sorted(idx))
        self.assertTrue(all(labs[i] >> 16 == idx[i] for i in range(50)))
        self.assertNotEqual(idx, self.derived("--keep", "0.25", "--seed", "4")[0])

    def test_crop_keeps_and_cut_drops_the_points_inside_a_box(self):
        pts, labs = self.derived("--crop", "0", "0.5", "-1", "1", "-2", "0")  # x of 0.05-0.45
        idx = [int(pts[4 * i + 3]) for i in range(len(labs))]
        self.assertEqual(idx, [i for i in range(200) if (i // 2) % 10 < 5])
        self.assertTrue(all(labs[i] >> 16 == idx[i] for i in range(len(idx))))
        pts, labs = self.derived("--cut", "0", "0.5", "-1", "1", "-2", "0")
        self.assertEqual([int(pts[4 * i + 3]) for i in range(len(labs))],
                         [i for i in range(200) if (i // 2) % 10 >= 5])
        # z up to -1.745: the lower point of each pair
        _, labs = self.derived("--crop", "-1", "1", "-1", "1", "-2", "-1.745")
        self.assertEqual([lab >> 16 for lab in labs], list(range(0, 200, 2)))
        _, labs = self.derived("--crop", "-1", "1", "-1", "1", "-2", "-1.745",
                               "--cut", "-1", "1", "0.5", "1", "-2", "0")
        self.assertEqual(len(labs), 50)

    def test_shift_and_tilt_move_the_points(self):
        pts, _ = self.derived("--shift", "100", "-2", "1.73")
        self.assertAlmostEqual(pts[0], 100.05, places=4)
        self.assertAlmostEqual(pts[1], -1.95, places=4)
        self.assertAlmostEqual(pts[2], -0.02, places=4)
        pts, _ = self.derived("--tilt", "0", "90")  # pitch 90: x -> -z, z -> x
        self.assertAlmostEqual(pts[0], -1.75, places=4)
        self.assertAlmostEqual(pts[2], -0.05, places=4)
        pts, _ = self.derived("--tilt", "90", "0")  # roll 90: y -> z, z -> -y
        self.assertAlmostEqual(pts[1], 1.75, places=4)
        self.assertAlmostEqual(pts[2], 0.05, places=4)

    def test_moved_vegetation_keeps_its_truth(self):
        # vegetation below -1.2975 m is ground under SemanticKITTI's rule, above it is not
        write_scan(self.src, [0, 0, -1.5, 0, 0, 0, -1.0, 1, 5, 0, -1.5, 2],
                   [(7 << 16) | 70, 70, 40])
        _, labs = self.derived("--shift", "0", "0", "5")
        self.assertEqual(list(labs), [(7 << 16) | 72, 99, 40])
        _, labs = self.derived("--voxel", "0.1")  # z unchanged: the classes stay
        self.assertEqual(list(labs), [(7 << 16) | 70, 70, 40])

    def test_mirror_adds_reflections_under_the_road_as_outliers(self):
        # the grid lies at z -1.75 / -1.74: raise half of it to 1 m above the road
        pts = read(self.src + ".bin", "f")
        for i in range(100):
            pts[4 * i + 2] = -0.73
        with open(self.src + ".bin", "wb") as f:
            f.write(pts.tobytes())
        out, labs = self.derived("--mirror", "0.1")
        self.assertEqual(len(labs), 220)
        self.assertEqual(list(out[:800]), list(pts))  # the scan itself unchanged, first
        self.assertEqual(set(labs[200:]), {1})
        for r in range(200, 220):
            self.assertAlmostEqual(out[4 * r + 2], -2.73, places=4)  # -0.73 mirrored in -1.73
            self.assertLess(int(out[4 * r + 3]), 100)  # a copy of a raised point

    def test_bad_input_is_refused(self):
        out = os.path.join(self.dir, "bad")
        for args in (["--voxel", "0"], ["--keep", "1.5"], ["--shift", "1", "2"],
                     ["--tilt", "nan", "0"], ["--voxel"], ["--mirror", "0.9"],
                     ["--crop", "1", "0", "0", "1", "0", "1"], ["--cut", "0", "1", "0", "1", "0"],
                     ["--crop", "0", "1", "0", "1", "0", "inf"]):
            self.assertEqual(self.run_script(*(args + [out, self.src + ".bin"])).returncode, 2,
                             args)
        with open(os.path.join(self.dir, "odd.bin"), "wb") as f:
            f.write(b"\0" * 10)
        res = self.run_script("--voxel", "0.1", out, os.path.join(self.dir, "odd.bin"))
        self.assertEqual(res.returncode, 1)
        self.assertIn("not KITTI", res.stderr)
        with open(self.src + ".label", "wb") as f:
            f.write(b"\0" * 8)
        res = self.run_script("--voxel", "0.1", out, self.src + ".bin")
        self.assertEqual(res.returncode, 1)
        self.assertIn("labels for", res.stderr)


if __name__ == "__main__":
    unittest.main()
