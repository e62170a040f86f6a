#!/usr/bin/env python3
"""package.xml's dependencies that are missing on this machine, offline (no rosdep database):
used by scripts/common.sh when an installed ROS is used. A ROS package counts as installed when
<prefix>/share/<name>/package.xml exists under CMAKE_PREFIX_PATH, ROS_PACKAGE_PATH, /opt/ros/
$ROS_DISTRO or /usr; a system key when the file, command or Python module it provides is there.

  ros_deps.py [--roles build,exec,test] [--missing] [--apt-names --distro noetic]
prints one key per line (with --apt-names: the apt package to install for each, Ubuntu/ROS
naming: ros-<distro>-<name> for ROS packages)."""
import argparse
import glob
import importlib.util
import os
import shutil
import xml.etree.ElementTree as ET

ROOT = os.path.dirname(os.path.dirname(os.path.realpath(__file__)))
ROLES = {"build": ("depend", "build_depend", "buildtool_depend", "build_export_depend"),
         "exec": ("depend", "exec_depend", "build_export_depend"),
         "test": ("test_depend",)}
# System keys: (how to tell it is installed, apt package on Debian/Ubuntu per rosdep's base.yaml
# and python.yaml).
SYSTEM = {
    "eigen": (lambda: os.path.exists("/usr/include/eigen3/Eigen/Core"), "libeigen3-dev"),
    "libpcl-all-dev": (lambda: bool(glob.glob("/usr/include/pcl-1.*/pcl/point_cloud.h")),
                       "libpcl-dev"),
    "boost": (lambda: os.path.exists("/usr/include/boost/version.hpp"), "libboost-all-dev"),
    "gtest": (lambda: os.path.exists("/usr/include/gtest/gtest.h")
              or os.path.isdir("/usr/src/googletest"), "libgtest-dev"),
    "python3-numpy": (lambda: importlib.util.find_spec("numpy") is not None, "python3-numpy"),
    "python3-nose": (lambda: importlib.util.find_spec("nose") is not None, "python3-nose"),
    "python3-rospkg": (lambda: importlib.util.find_spec("rospkg") is not None, "python3-rospkg"),
    "python3-yaml": (lambda: importlib.util.find_spec("yaml") is not None, "python3-yaml"),
    "xvfb": (lambda: shutil.which("Xvfb") is not None, "xvfb"),
    "imagemagick": (lambda: shutil.which("convert") is not None, "imagemagick"),
}


def declared(roles):
    tags = {t for r in roles for t in ROLES[r]}
    root = ET.parse(os.path.join(ROOT, "package.xml")).getroot()
    out = []
    for el in root:
        if el.tag in tags and el.text and el.text.strip() not in out:
            out.append(el.text.strip())
    return out


def ros_prefixes():
    prefixes = []
    for var in ("CMAKE_PREFIX_PATH",):
        prefixes += [p for p in os.environ.get(var, "").split(os.pathsep) if p]
    share_dirs = [os.path.join(p, "share") for p in prefixes]
    share_dirs += [p for p in os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep) if p]
    if os.environ.get("ROS_DISTRO"):
        share_dirs.append(os.path.join("/opt/ros", os.environ["ROS_DISTRO"], "share"))
    share_dirs.append("/usr/share")
    return share_dirs


def installed(key, share_dirs):
    if key in SYSTEM:
        return SYSTEM[key][0]()
    return any(os.path.exists(os.path.join(d, key, "package.xml")) for d in share_dirs)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--roles", default="build,exec,test")
    ap.add_argument("--missing", action="store_true")
    ap.add_argument("--apt-names", action="store_true")
    ap.add_argument("--distro", default=os.environ.get("ROS_DISTRO", "noetic"))
    a = ap.parse_args()
    keys = declared(a.roles.split(","))
    share_dirs = ros_prefixes()
    if a.missing:
        keys = [k for k in keys if not installed(k, share_dirs)]
    for k in keys:
        if a.apt_names:
            print(SYSTEM[k][1] if k in SYSTEM else "ros-%s-%s" % (a.distro, k.replace("_", "-")))
        else:
            print(k)


if __name__ == "__main__":
    main()
