"""scripts/soak.py --params / --set: the private parameters each nodelet of a soak run gets (the
YAML file's, then --set for every nodelet or one), and malformed input refused by name before
anything starts."""
import os
import subprocess
import sys
import tempfile
import unittest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "scripts"))
import soak  # noqa: E402

BOTH = ["soak_voxel", "soak_normal"]


class NodeletParams(unittest.TestCase):
    def write(self, text):
        fd, path = tempfile.mkstemp(suffix=".yaml")
        with os.fdopen(fd, "w") as f:
            f.write(text)
        self.addCleanup(os.remove, path)
        return path

    def test_nothing_given_sets_nothing(self):
        self.assertEqual(soak.nodelet_params("", [], BOTH), {"soak_voxel": {}, "soak_normal": {}})

    def test_yaml_for_every_nodelet_then_set_for_one_or_all(self):
        path = self.write("voxel_size: 0.2\nthreads: 2\nscan_type: auto\n")
        p = soak.nodelet_params(path, ["normal:threads=1", "max_range=80"], BOTH)
        self.assertEqual(p["soak_voxel"], {"voxel_size": 0.2, "threads": 2, "scan_type": "auto",
                                           "max_range": 80})
        self.assertEqual(p["soak_normal"], {"voxel_size": 0.2, "threads": 1,
                                            "scan_type": "auto", "max_range": 80})

    def test_values_are_typed_as_yaml_scalars(self):
        p = soak.nodelet_params("", ["voxel:veg_filter=true", "voxel:tile_size=0.7",
                                     "voxel:knn_backend=kdtree"], ["soak_voxel"])
        self.assertIs(p["soak_voxel"]["veg_filter"], True)
        self.assertEqual(p["soak_voxel"]["tile_size"], 0.7)
        self.assertEqual(p["soak_voxel"]["knn_backend"], "kdtree")

    def test_set_for_a_nodelet_not_in_the_run_changes_nothing(self):
        p = soak.nodelet_params("", ["normal:threads=1"], ["soak_voxel"])
        self.assertEqual(p, {"soak_voxel": {}})

    def test_malformed_input_is_refused_by_name(self):
        for item in ("threads", "=1", "normal:=1", "lidar:threads=1"):
            with self.assertRaises(ValueError) as e:
                soak.nodelet_params("", [item], BOTH)
            self.assertIn(item, str(e.exception))
        nested = self.write("voxel:\n  voxel_size: 0.2\n")
        with self.assertRaises(ValueError) as e:
            soak.nodelet_params(nested, [], BOTH)
        self.assertIn("not a flat YAML", str(e.exception))
        broken = self.write("voxel_size: [0.2\n")
        with self.assertRaises(ValueError) as e:
            soak.nodelet_params(broken, [], BOTH)
        self.assertIn(broken, str(e.exception))

    def test_command_line_refuses_before_starting_anything(self):
        # No ROS master, no data: the refusal must come first, naming the entry.
        env = dict(os.environ, ROS_MASTER_URI="http://localhost:1")
        r = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "soak.py"), "run",
                            "--minutes", "0.1", "--set", "lidar:threads=1"],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env, timeout=60)
        self.assertNotEqual(r.returncode, 0)
        self.assertIn(b"lidar:threads=1", r.stderr)
        r = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "soak.py"), "run",
                            "--minutes", "0.1", "--params", "/nonexistent/p.yaml"],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env, timeout=60)
        self.assertNotEqual(r.returncode, 0)
        self.assertIn(b"/nonexistent/p.yaml", r.stderr)


if __name__ == "__main__":
    unittest.main()
