"""Install space: the package installed into a fresh prefix installs exactly its public headers,
each of which compiles on its own in C++14, and runs the demo with only that install space
sourced (run by catkin_add_nosetests after the build).

The workspace build is installed once with `cmake --install` into a staging directory (DESTDIR
under /tmp: nothing is written into the workspace, its install/ folder included). Then:
- the headers under include/ground_filter/ are exactly PUBLIC_HEADERS (the API: a private header
  of src/ that gets installed, or a public one that does not, fails);
- each installed header compiles alone with -std=c++14 against the install space only (a
  public header that includes a private one fails);
- in a clean environment (`env -i`, only the staged install/setup.bash sourced, a master on a
  free port), `roslaunch ground_filter demo.launch scans:=N` must load the nodelet from the
  staged prefix (checked in the nodelet manager's /proc/PID/maps), print N scans split with
  counts conserved, and end by itself.
"""
import glob
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
import unittest

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.realpath(__file__))),
                                "scripts"))
from ros_launch_helpers import Process, free_port, loopback_env  # noqa: E402

CONFIG = "gf_install_test.json"  # written by CMakeLists.txt next to where this test runs
ROOT = os.path.dirname(os.path.dirname(os.path.realpath(__file__)))
# The public API, relative to include/ground_filter/: the filters and their parameters, the
# cloud view, the neighbour interface and factory, height above ground; and the nodelets'
# dynamic_reconfigure Config types (generated). Everything else is private (src/), the
# evaluation kit too (src/eval/: linked statically into the tools), and the CUDA library's
# interface (cuda/include/: linked statically into the core library, reached through
# knn_backend "gpu").
PUBLIC_HEADERS = {
    "cloud_view.h", "ground_filter.h",
    "morph_ground_params.h", "neighbor_search.h", "normal_ground_filter.h",
    "normal_ground_filter_params.h",
    "param_parse.h", "param_table.h", "point_field.h", "voxel_ground_filter.h", "voxel_ground_filter_params.h",
    "working_volume.h", "working_volume_params.h", "height_above_ground.h", "build_info.h",
    "params/param_def.h", "params/normal_filter_settings.h",
    "NormalGroundFilterConfig.h", "VoxelGroundFilterConfig.h",
}
SCANS = 5
TIMEOUT_S = 120


class InstallSpaceTest(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        if not os.path.exists(CONFIG):
            raise RuntimeError("%s not found in %s: run this test through catkin (CMakeLists.txt "
                               "writes it)" % (CONFIG, os.getcwd()))
        with open(CONFIG) as f:
            cfg = json.load(f)
        cls.build_dir = cfg["build_dir"]
        cls.prefix = cfg["install_prefix"]
        cls.stage = tempfile.mkdtemp(prefix="gf_install_test_")
        t0 = time.monotonic()
        env = dict(os.environ, DESTDIR=cls.stage)
        p = subprocess.run(["cmake", "--install", cls.build_dir], env=env,
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                           universal_newlines=True)
        cls.install_error = None if p.returncode == 0 else p.stdout[-4000:]
        cls.install = os.path.join(cls.stage, cls.prefix.lstrip("/"))
        cls.install_s = time.monotonic() - t0

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.stage, ignore_errors=True)

    def installed_headers(self):
        self.assertIsNone(self.install_error, "cmake --install failed:\n%s" % self.install_error)
        inc = os.path.join(self.install, "include", "ground_filter")
        return {os.path.relpath(h, inc)
                for h in glob.glob(os.path.join(inc, "**", "*.h"), recursive=True)}

    def test_only_public_headers_installed(self):
        installed = self.installed_headers()
        private = {os.path.relpath(h, ROOT)
                   for h in glob.glob(os.path.join(ROOT, "src", "**", "*.h"), recursive=True)}
        leaked = sorted(h for h in installed - PUBLIC_HEADERS
                        if any(p.endswith("/" + os.path.basename(h)) for p in private))
        self.assertEqual(leaked, [], "private headers (src/) installed")
        self.assertEqual(sorted(installed - PUBLIC_HEADERS), [],
                         "installed but not public (move it to src/ or add it to PUBLIC_HEADERS)")
        self.assertEqual(sorted(PUBLIC_HEADERS - installed), [], "public headers not installed")

    def test_public_headers_compile_alone_in_cxx14(self):
        """Each installed header alone, C++14, with only the install space's include/ (plus
        Eigen, PCL and the system's ROS headers for the generated Config types)."""
        inc = os.path.join(self.install, "include")
        pcl = sorted(glob.glob("/usr/include/pcl-1.*"))
        flags = ["-std=c++14", "-fsyntax-only", "-x", "c++", "-I" + inc,
                 "-isystem", "/usr/include/eigen3"] + (["-isystem", pcl[-1]] if pcl else [])
        ros = os.environ.get("ROS_ROOT", "")
        if ros:  # /opt/ros/<distro>/share/ros -> /opt/ros/<distro>/include
            flags += ["-isystem", os.path.join(os.path.dirname(os.path.dirname(ros)), "include")]
        bad = []
        for h in sorted(self.installed_headers()):
            p = subprocess.run(["g++"] + flags + ["-"], input="#include <ground_filter/%s>\n" % h,
                               stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                               universal_newlines=True)
            if p.returncode != 0:
                bad.append("%s:\n%s" % (h, p.stdout[-1500:]))
        self.assertEqual(bad, [], "headers that do not compile alone in C++14")

    def test_demo_from_install_space(self):
        self.assertIsNone(self.install_error, "cmake --install failed:\n%s" % self.install_error)
        install = self.install
        install_s = self.install_s
        for rel in ("setup.bash", "lib/libground_filter_nodelets.so",
                    "lib/ground_filter/make_bag.py",
                    "lib/ground_filter/scene_publisher", "lib/ground_filter/demo_monitor",
                    "share/ground_filter/package.xml", "share/ground_filter/nodelet_plugins.xml",
                    "share/ground_filter/launch/demo.launch",
                    "share/ground_filter/rviz/ground_filter.rviz",
                    "include/ground_filter/ground_filter.h"):
            self.assertTrue(os.path.exists(os.path.join(install, rel)), "not installed: " + rel)

        home = os.path.join(self.stage, "home")
        os.makedirs(home)
        port = free_port()
        # A clean environment: nothing of the build or devel space, only the install space.
        # ROS_HOSTNAME/ROS_IP: the caller's when they resolve, else loopback (containers).
        ros = loopback_env(master_port=port)
        clean = {"PATH": "/usr/bin:/bin", "HOME": home, "ROS_HOME": os.path.join(home, ".ros"),
                 "ROS_MASTER_URI": ros["ROS_MASTER_URI"], "LANG": "C.UTF-8",
                 "PYTHONUNBUFFERED": "1"}  # roslaunch's "started with pid" lines as they come
        clean.update({k: ros[k] for k in ("ROS_HOSTNAME", "ROS_IP") if k in ros})
        script = (
            "set -e; source '%s/setup.bash'; "
            "echo PKG=$(rospack find ground_filter); "
            "echo PLUGIN=$(rospack plugins --attrib=plugin nodelet | grep '^ground_filter '); "
            # The Python tools are installed too (catkin_install_python).
            "echo MAKE_BAG=$(rosrun ground_filter make_bag.py --help | head -n 1); "
            "exec roslaunch -p %d ground_filter demo.launch scans:=%d rate:=5"
            % (install, port, SCANS))
        launch = Process(["env", "-i"] + ["%s=%s" % kv for kv in clean.items()] +
                         ["bash", "-c", script])
        lines, maps_lib, manager_pid = launch.lines, None, None
        deadline = time.monotonic() + TIMEOUT_S
        try:
            while launch.running() and time.monotonic() < deadline:
                text = "".join(lines)
                if manager_pid is None:
                    m = re.search(r"process\[ground_filter_manager-\d+\]: started with pid "
                                  r"\[(\d+)\]", text)
                    manager_pid = int(m.group(1)) if m else None
                if manager_pid and maps_lib is None:
                    maps_lib = self.loaded_library(manager_pid)
                time.sleep(0.05)
        finally:
            launch.stop()
        out = launch.output()
        tail = "\n" + out[-6000:]
        self.assertLess(time.monotonic(), deadline, "demo did not end within %d s" % TIMEOUT_S +
                        tail)

        self.assertIn("PKG=%s/share/ground_filter" % install, out, tail)
        self.assertIn("%s/share/ground_filter/nodelet_plugins.xml" % install, out, tail)
        self.assertRegex(out, r"MAKE_BAG=usage: make_bag\.py", "rosrun make_bag.py failed" + tail)
        self.assertIsNotNone(maps_lib, "nodelet library not found in the manager's maps" + tail)
        self.assertTrue(os.path.realpath(maps_lib).startswith(os.path.realpath(install) + "/lib/"),
                        "nodelet loaded from %s, not from the install space" % maps_lib)
        rows = re.findall(r"^\s*(\d+)\s+[\d.]+\s+(\d+)\s+(\d+)\s+(\d+)\s", out, re.M)
        self.assertEqual(len(rows), SCANS, "expected %d scan lines" % SCANS + tail)
        for _, points, ground, nonground in rows:
            self.assertEqual(int(ground) + int(nonground), int(points), tail)
            self.assertGreater(int(ground), 0, tail)
            self.assertGreater(int(nonground), 0, tail)
        self.assertIn("[demo_monitor] summary: %d scans" % SCANS, out, tail)
        # The monitor stops the launch itself (~shutdown_launch): no red REQUIRED message.
        self.assertIn("[demo_monitor] done: stopping the launch", out, tail)
        self.assertNotIn("REQUIRED process", out, tail)
        self.assertEqual(launch.proc.returncode, 0, "roslaunch exit status" + tail)
        print("install %.1f s into %s; demo from the install space: %d scans, nodelet library %s"
              % (install_s, install, len(rows), maps_lib))

    @staticmethod
    def loaded_library(pid):
        """Path of libground_filter_nodelets.so mapped by process `pid` (None if not yet)."""
        try:
            with open("/proc/%d/maps" % pid) as f:
                for line in f:
                    if line.rstrip().endswith("/libground_filter_nodelets.so"):
                        return line.split()[-1]
        except OSError:
            pass
        return None


if __name__ == "__main__":
    unittest.main()
