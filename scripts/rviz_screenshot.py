#!/usr/bin/env python3
"""Runs the demo with rviz (launch/demo.launch gui:=true) on the current X display, takes
screenshots of the root window until both the ground (green) and the non-ground (red) clouds
are on screen, and saves that screenshot.

Meant to run under a virtual X server with software OpenGL, e.g.
  LIBGL_ALWAYS_SOFTWARE=1 xvfb-run -a -s "-screen 0 1280x800x24" \\
      scripts/rviz_screenshot.py --out /tmp/gf_rviz.png [--small rviz/demo.png]
Needs the package built and its devel (or install) space sourced, imagemagick (import, convert).
Exit status 0 when both colours were seen (the PNG path is printed), 1 otherwise.
"""
import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.realpath(__file__)))
from ros_launch_helpers import free_port, roslaunch  # noqa: E402


def colour_counts(png):
    """(green, red) pixel counts of a PNG, read through imagemagick's raw RGB output.

    rviz/ground_filter.rviz draws ground 0;200;0 and non-ground 230;0;0 as flat-coloured points;
    the thresholds leave room for blending at point edges."""
    size = subprocess.run(["identify", "-format", "%w %h", png], check=True,
                          stdout=subprocess.PIPE, universal_newlines=True).stdout.split()
    w, h = int(size[0]), int(size[1])
    raw = subprocess.run(["convert", png, "-depth", "8", "rgb:-"], check=True,
                         stdout=subprocess.PIPE).stdout
    rgb = np.frombuffer(raw, dtype=np.uint8)[:w * h * 3].reshape(h, w, 3).astype(np.int16)
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    green = int(((g >= 150) & (r <= 80) & (b <= 80)).sum())
    red = int(((r >= 170) & (g <= 70) & (b <= 70)).sum())
    return green, red


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog=__doc__.split("\n", 1)[1])
    ap.add_argument("--out", required=True, help="screenshot PNG to write")
    ap.add_argument("--small", help="also write a reduced copy (e.g. rviz/demo.png for the README)")
    ap.add_argument("--timeout", type=float, default=90.0, help="give up after this long [s]")
    ap.add_argument("--min-pixels", type=int, default=300,
                    help="pixels of each colour needed (default 300)")
    ap.add_argument("--settle", type=float, default=3.0,
                    help="after both colours appear, wait this long and shoot again [s]")
    ap.add_argument("launch_args", nargs="*", help="extra demo.launch args, e.g. seed:=2")
    a = ap.parse_args(argv)
    if not os.environ.get("DISPLAY"):
        print("rviz_screenshot.py: no DISPLAY (run it under xvfb-run)", file=sys.stderr)
        return 1

    work = tempfile.mkdtemp(prefix="gf_rviz_")
    env = dict(os.environ, LIBGL_ALWAYS_SOFTWARE="1")
    env.setdefault("ROS_HOME", os.path.join(work, "ros"))
    # A private master on a free port, reachable through loopback even without a resolvable
    # hostname (containers).
    launch = roslaunch(["ground_filter", "demo.launch", "gui:=true", "scans:=0"] + a.launch_args,
                       port=free_port(), env=env)
    lines = launch.lines
    shot = os.path.join(work, "shot.png")
    found, counts, shots = False, (0, 0), 0
    deadline = time.monotonic() + a.timeout
    try:
        while time.monotonic() < deadline and launch.running():
            time.sleep(2.0)
            # Scans flowing through the filter (demo_monitor lines) before looking at the screen.
            if len(re.findall(r"^\s*\d+\s+[\d.]+\s+\d+\s+\d+\s+\d+\s", "".join(lines),
                              re.M)) < 2:
                continue
            if subprocess.run(["import", "-window", "root", shot],
                              stderr=subprocess.DEVNULL).returncode != 0:
                continue
            shots += 1
            counts = colour_counts(shot)
            if min(counts) >= a.min_pixels:
                # Drawn: let rviz accumulate a couple more frames, then keep the final picture.
                time.sleep(a.settle)
                subprocess.run(["import", "-window", "root", shot], check=True)
                counts = colour_counts(shot)
                found = min(counts) >= a.min_pixels
                break
    finally:
        launch.stop()
    if os.path.exists(shot):
        os.makedirs(os.path.dirname(os.path.abspath(a.out)), exist_ok=True)
        shutil.copyfile(shot, a.out)
    print("screenshots taken: %d; last: green %d px, red %d px (need %d each)"
          % (shots, counts[0], counts[1], a.min_pixels))
    if not found:
        print("rviz_screenshot.py: ground and non-ground colours not both on screen; roslaunch "
              "output:\n" + "".join(lines)[-5000:], file=sys.stderr)
        shutil.rmtree(work, ignore_errors=True)
        return 1
    print("screenshot PNG: %s" % os.path.abspath(a.out))
    if a.small:
        # The rviz window (1200x800 at 0,0 in rviz/ground_filter.rviz) as a small palette PNG.
        subprocess.run(["convert", shot, "-crop", "1200x800+0+0", "+repage", "-resize", "900x",
                        "-colors", "48", "-strip", "png8:" + a.small], check=True)
        print("reduced copy: %s (%d bytes)" % (a.small, os.path.getsize(a.small)))
    shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
