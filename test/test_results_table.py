"""scripts/results_table.py: the README's table composed from the saved tables of its steps
(planted here in the formats of eval_all.sh, run_peers.sh, sensor_sweep.py and speed_table.sh),
each figure in its row and column; steps not run named; bad options refused."""
import os
import subprocess
import sys
import tempfile
import unittest

ROOT = os.path.dirname(os.path.dirname(os.path.realpath(__file__)))
TOOL = os.path.join(ROOT, "scripts", "results_table.py")
HEAD = "| group | method | files | P % | R % | F1 % | ms (sum) |\n|---|---|---|---|---|---|---|\n"
EVAL = HEAD + """| kitti seq00 0-2 | voxel | 3 | 1 | 1 | 97.22 | 78 |
| kitti seq00 0-2 | normal | 3 | 1 | 1 | 96.88 | 258 |
| offroad rellis3d | voxel | 1 | 1 | 1 | 94.56 | 36 |
| offroad rellis3d | normal | 1 | 1 | 1 | 95.75 | 66 |
| isprs 8 tiles | voxel | 8 | 1 | 1 | 97.05 | 869 |
| isprs 8 tiles | normal | 8 | 1 | 1 | 97.04 | 870 |
| isprs 8 tiles, preset airborne | voxel | 8 | 1 | 1 | 11.11 | 847 |
| airborne 2 tiles | voxel | 2 | 1 | 1 | 94.32 | 68 |
| airborne 2 tiles | normal | 2 | 1 | 1 | 94.31 | 67 |
| gen street (lidar:1,2) | voxel | 2 | 1 | 1 | 22.22 | 81 |
"""
HELDOUT = HEAD + """| held-out kitti (seq04 000056, spvnas 000000) | voxel | 2 | 1 | 1 | 95.49 | 71 |
| held-out kitti (seq04 000056, spvnas 000000) | normal | 2 | 1 | 1 | 93.82 | 168 |
| held-out isprs 7 tiles | voxel | 7 | 1 | 1 | 96.90 | 490 |
| held-out isprs 7 tiles | normal | 7 | 1 | 1 | 96.91 | 499 |
| held-out airborne_pdal 5 tiles | voxel | 5 | 1 | 1 | 66.29 | 1162 |
"""
PEERS = "peers scored by ground_filter_eval\n" + HEAD + """| kitti seq00 0-2 | patchworkpp | 3 | 1 | 1 | 96.57 | 50 |
| kitti seq00 0-2 | linefit | 3 | 1 | 1 | 93.75 | 30 |
| kitti seq00 0-2 | linefit_h1.28 | 3 | 1 | 1 | 33.33 | 30 |
| offroad rellis3d | linefit | 1 | 1 | 1 | 44.44 | 9 |
| offroad rellis3d | linefit_h1.28 | 1 | 1 | 1 | 93.51 | 9 |
| offroad rellis3d | patchworkpp | 1 | 1 | 1 | 94.15 | 9 |
| isprs 8 tiles | csf | 8 | 1 | 1 | 83.65 | 9 |
| held-out kitti 2 frames | patchworkpp | 2 | 1 | 1 | 93.42 | 49 |
"""
SWEEP = """F1 % (ground = positive), mean over 4 worlds x 4 heights, seeds 1,2 pooled
| sensor | normal stride | normal | voxel | patchworkpp | linefit | linefit, true height |
|---|---|---|---|---|---|---|
| 16 beams | 2 | 91.9 | 90.3 | 74.1 | 8.2 | 60.8 |
| all 128 placements: mean | | 94.5 | 93.1 | 75.8 | 16.3 | 73.5 |
| all 128 placements: lowest | | 80.0 | 70.0 | 10.0 | 1.0 | 5.0 |
"""
SPEED = """CPU: Test CPU (avx2 fma); best SIMD path avx2; 2 cores; load 0.1 -> 0.2; 3 rounds
| tool | ms per KITTI frame: median (range) of per-frame medians | × Patchwork++ |
|---|---|---|
| voxel | 5.5 (4.8–6.7) | 0.25 |
| normal avx2, 1 thread | 46.3 (43.3–57.6) | 2.1 |
| normal avx2, 2 threads | 24.8 (23.5–28.7) | 1.1 |
| patchworkpp | 19.7 (19.1–21.9) | 1.00 |
| pcl_ransac | 45.7 (41.0–54.4) | 2.3 |
| pcl_ransac_native | 3.2 (2.7–5.5) | 0.16 |
"""


def run(*args):
    p = subprocess.run([sys.executable, TOOL] + list(args), stdout=subprocess.PIPE,
                       stderr=subprocess.PIPE, universal_newlines=True, timeout=60)
    return p.returncode, p.stdout, p.stderr


class ComposedTable(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        for name, text in (("eval", EVAL), ("heldout", HELDOUT), ("peers", PEERS),
                           ("sweep", SWEEP), ("speed", SPEED)):
            with open(os.path.join(self.tmp.name, name + ".md"), "w") as f:
                f.write(text)

    def tearDown(self):
        self.tmp.cleanup()

    def rows(self):
        rc, out, err = run("--from", self.tmp.name)
        self.assertEqual(rc, 0, err)
        rows = {}
        for line in out.splitlines():
            if line.startswith("| ") and not line.startswith("| method"):
                cells = [c.strip() for c in line.strip().strip("|").split("|")]
                rows[cells[0].split(" (")[0].strip("*")] = cells[1:]
        return out, rows

    def test_every_figure_in_its_cell(self):
        out, rows = self.rows()
        self.assertIn("Speed step: CPU: Test CPU (avx2 fma); best SIMD path avx2", out)
        # KITTI, RELLIS, ISPRS, ALS, held-out, 8 sensors, ms AVX-512, ms AVX2
        self.assertEqual(rows["voxel"], ["97.22", "94.56", "97.05", "94.32", "95.49 / 96.90",
                                         "93.1", "", "5.5 (4.8–6.7)"])
        self.assertEqual(rows["normal-vector"][:6], ["96.88", "95.75", "97.04", "94.31",
                                                     "93.82 / 96.91", "94.5"])
        self.assertEqual(rows["normal-vector"][7], "46.3 (43.3–57.6)")
        self.assertEqual(rows["normal-vector, 2 threads"][7], "24.8 (23.5–28.7)")
        # Patchwork++ on KITTI and RELLIS; not applicable to airborne tiles
        self.assertEqual(rows["Patchwork++"][:5], ["96.57", "94.15", "–", "–", "93.42 / –"])
        self.assertEqual(rows["Patchwork++"][7], "19.7 (19.1–21.9)")
        # linefit: KITTI from the 1.8 m driver, RELLIS from the 1.28 m one
        self.assertEqual(rows["linefit"][:2], ["93.75", "93.51"])
        self.assertEqual(rows["linefit"][5], "16.3; 73.5 at the true height")
        self.assertEqual(rows["PCL `SACSegmentation` plane, RANSAC 0.2 m"][7],
                         "45.7 (41.0–54.4); `-march=native`: 3.2 (2.7–5.5)")
        # CSF: ISPRS measured, the rest of its cells not
        self.assertEqual(rows["CSF"][2], "83.65")
        self.assertEqual(rows["CSF"][0], "not run")
        self.assertNotIn("11.11", out)  # a preset row is not the defaults' figure
        self.assertNotIn("22.22", out)  # nor a generated group

    def test_steps_not_run_are_named(self):
        os.remove(os.path.join(self.tmp.name, "speed.md"))
        os.remove(os.path.join(self.tmp.name, "sweep.md"))
        _, rows = self.rows()
        self.assertEqual(rows["voxel"][5:], ["not run", "", "not run"])
        self.assertEqual(rows["normal-vector"][6:], ["not run", "not run"])
        self.assertEqual(rows["voxel"][0], "97.22")

    def test_bad_options(self):
        rc, _, err = run("--skip", "eval,nosuch")
        self.assertEqual(rc, 1)
        self.assertIn("unknown step nosuch", err)
        rc, _, err = run("--from", os.path.join(self.tmp.name, "missing"))
        self.assertEqual(rc, 1)
        self.assertIn("no folder", err)


if __name__ == "__main__":
    unittest.main()
