"""scripts/placement_sweep.py: its seeded placements are the documented ones on any Python 3.8+
(each set's first scene pinned), and its F1 are ground_filter_eval's own."""
import json
import os
import subprocess
import sys
import unittest

ROOT = os.path.dirname(os.path.dirname(os.path.realpath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "scripts"))
from gf_data import built_tool  # noqa: E402

SCRIPT = os.path.join(ROOT, "scripts", "placement_sweep.py")
EVAL = built_tool()


def run(*args):
    return subprocess.run([sys.executable, SCRIPT] + list(args), check=True,
                          stdout=subprocess.PIPE, universal_newlines=True).stdout


class TestPlacementSweep(unittest.TestCase):
    def test_the_sets_are_the_documented_ones(self):
        high = run("sparse-high", "--list").split()
        self.assertEqual(len(high), 120)
        self.assertEqual(len(set(high)), 120)
        self.assertEqual(high[0], "builtin:trail:2:sensor_height=3.35,beams=32,vertical_min_deg="
                                  "-13.1,vertical_max_deg=15.2,uniform_beams=1,azimuth_steps=2048")
        self.assertEqual(high[-1], "builtin:trail:17:sensor_height=3.67,beams=32,vertical_min_deg="
                                   "-15.3,vertical_max_deg=13.2,uniform_beams=1,azimuth_steps=512")
        general = run("general", "--list").split()
        self.assertEqual(len(general), 205)
        self.assertEqual(general[0], "builtin:verge:50:sensor_height=2.21,slope_x=0.073,slope_y="
                                     "-0.07,curb_height=0.04,ramp_height=1.9,mount_roll_deg=-0.2,"
                                     "grass_roughness=0.091")
        self.assertTrue(general[-1].startswith("builtin:lidar:34:sensor_height=1.75,"))
        registered = run("registered", "--list").split()
        self.assertEqual(len(registered), 80)
        self.assertEqual(len(set(registered)), 80)
        self.assertEqual(registered[0], "builtin:mls:35:layout=trail,positions=3,"
                                        "position_step=11.9,world_offset_z=-36.5")

    @unittest.skipIf(EVAL is None, "ground_filter_eval not built")
    def test_scores_are_the_eval_tools(self):
        out = run("sparse-high", "--first", "2", "--methods", "voxel", "--per-scan",
                  "--eval", EVAL)
        rows = [l.split("\t") for l in out.splitlines() if l.count("\t") == 1]
        self.assertEqual([r[0] for r in rows[:1]], ["voxel"])  # the header
        self.assertEqual(len(rows), 3)
        for f1, scene in rows[1:]:
            js = subprocess.run([EVAL, "--json", "--method", "voxel", scene], check=True,
                                stdout=subprocess.PIPE).stdout
            self.assertAlmostEqual(float(f1), 100.0 * json.loads(js.decode())["pooled"]["f1"],
                                   places=2)
        self.assertIn("| voxel |", out)
        self.assertIn("scan_type auto: 2 ground", out)  # each scene's decision, counted once


if __name__ == "__main__":
    unittest.main()
