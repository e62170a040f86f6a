"""rviz under Xvfb with the demo running: the screenshot must show both the ground (green) and
the non-ground (red) cloud (run by catkin_add_nosetests after the build).

scripts/rviz_screenshot.py does the work under `xvfb-run` with software OpenGL; the PNG is
written to the build directory (never into the repository) and its path is printed.
"""
import os
import subprocess
import sys
import tempfile
import unittest

ROOT = os.path.dirname(os.path.dirname(os.path.realpath(__file__)))
SCRIPT = os.path.join(ROOT, "scripts", "rviz_screenshot.py")
sys.path.insert(0, os.path.join(ROOT, "scripts"))
from rviz_screenshot import colour_counts  # noqa: E402


class RvizScreenshotTest(unittest.TestCase):

    def test_screenshot_shows_ground_and_nonground(self):
        self._shoot("test_results_rviz_screenshot.png")

    def test_rviz_follows_name_and_topic(self):
        """Another nodelet name and input topic: rviz (in the nodelet's namespace, relative
        topics, input remapped) still shows both clouds."""
        self._shoot("test_results_rviz_screenshot_renamed.png", "name:=gf_renamed",
                    "topic:=/renamed/points")

    def _shoot(self, name, *launch_args):
        # catkin runs nosetests in the package's build directory; elsewhere fall back to /tmp.
        out_dir = os.getcwd() if os.access(os.getcwd(), os.W_OK) else tempfile.gettempdir()
        png = os.path.join(out_dir, name)
        if os.path.exists(png):
            os.remove(png)
        env = dict(os.environ, LIBGL_ALWAYS_SOFTWARE="1")
        p = subprocess.run(["xvfb-run", "-a", "-s", "-screen 0 1280x800x24", sys.executable,
                            SCRIPT, "--out", png, "--timeout", "120"] + list(launch_args),
                           env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                           universal_newlines=True, timeout=240)
        print(p.stdout[-3000:])
        print("rviz screenshot PNG: %s" % png)
        self.assertEqual(p.returncode, 0, p.stdout[-6000:])
        self.assertIn("screenshot PNG: " + png, p.stdout)
        # The saved file itself, read again: both colours present.
        green, red = colour_counts(png)
        self.assertGreaterEqual(green, 300, "too few ground (green) pixels in " + png)
        self.assertGreaterEqual(red, 300, "too few non-ground (red) pixels in " + png)


if __name__ == "__main__":
    unittest.main()
