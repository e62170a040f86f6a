"""scripts/common.sh's install logic without installing anything (GF_DRY_RUN=1, fake
/etc/os-release files): the package list per release, an installed ROS first, and the stops on
bad input (a ROS 2 distro, a release without Debian ROS packages). The real installs are run by
scripts/check_platform.sh bullseye (a Debian 11 root, stand-in /opt/ros/noetic)."""
import os
import subprocess
import tempfile
import unittest

ROOT = os.path.dirname(os.path.dirname(os.path.realpath(__file__)))
RELEASES = {  # (ID, VERSION_ID): (libclang-rt-dev listed, Debian ROS packages in the archive)
    ("debian", "11"): (False, True), ("debian", "12"): (True, True),
    ("debian", "13"): (True, True), ("ubuntu", "20.04"): (False, False),
    ("ubuntu", "22.04"): (False, True), ("ubuntu", "24.04"): (True, False)}


def run(script, os_id="debian", version="12", **env):
    with tempfile.NamedTemporaryFile("w", suffix="os-release", delete=False) as f:
        f.write('ID=%s\nVERSION_ID="%s"\nPRETTY_NAME="%s %s"\n' % (os_id, version, os_id, version))
    full_env = {k: v for k, v in os.environ.items() if not k.startswith("ROS_")}
    full_env.update(GF_OS_RELEASE=f.name, GF_DRY_RUN="1", **env)
    try:
        p = subprocess.run(["bash", "-c", "source scripts/common.sh; " + script], cwd=ROOT,
                           env=full_env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                           universal_newlines=True, timeout=60)
    finally:
        os.unlink(f.name)
    return p.returncode, p.stdout


class InstallDepsTest(unittest.TestCase):

    def test_package_lists_per_release(self):
        for (os_id, version), (rt, debian_ros) in RELEASES.items():
            rc, out = run('echo "LIST ${GF_APT_SYSTEM_TEST_PACKAGES[*]} ROS=${GF_DEBIAN_ROS}"',
                          os_id, version)
            line = [l for l in out.splitlines() if l.startswith("LIST ")][0]
            self.assertEqual(rc, 0, out)
            self.assertEqual("libclang-rt-dev" in line.split(), rt, (os_id, version, line))
            self.assertTrue(line.endswith("ROS=%d" % debian_ros), (os_id, version, line))
            self.assertNotIn("not one of the releases", out)

    def test_unknown_release_says_so(self):
        rc, out = run("true", "debian", "10")
        self.assertEqual(rc, 0)
        self.assertIn("not one of the releases these scripts know", out)

    def test_ros2_distro_stops(self):
        for distro in ("humble", "jazzy"):
            rc, out = run("gf_install_deps", ROS_DISTRO=distro)
            self.assertNotEqual(rc, 0, out)
            self.assertIn("ROS_DISTRO=%s is ROS 2" % distro, out)
            self.assertIn("nothing was installed or changed", out)
            self.assertNotIn("would run", out)

    def test_release_without_debian_ros_needs_an_installed_ros(self):
        if os.path.isdir("/opt/ros"):
            self.skipTest("/opt/ros exists here: the installed-ROS path applies")
        rc, out = run("gf_install_deps", "ubuntu", "20.04")
        self.assertNotEqual(rc, 0, out)
        self.assertIn("has no Debian ROS 1 packages", out)
        self.assertIn("ROS Noetic", out)
        self.assertNotIn("would run", out)

    def test_installed_ros_is_used_and_no_ros_package_is_apt_installed(self):
        # ROS_DISTRO set with catkin_make on PATH: that ROS is used as it is.
        rc, out = run("gf_install_deps", ROS_DISTRO="noetic")
        self.assertEqual(rc, 0, out)
        self.assertIn("using the installed ROS noetic", out)
        for line in out.splitlines():
            if "would run" in line and "apt-get install" in line:
                self.assertNotRegex(line, r"\b(catkin|ros-core-dev|libnodelet-dev|rviz)\b", line)


if __name__ == "__main__":
    unittest.main()
