#!/usr/bin/env python3
"""Writes test/rosdep_keys_focal.txt: every rosdep key that resolves on Ubuntu 20.04 (focal), the
platform of ROS Noetic's binaries, from a checkout of ros/rosdistro:
  - system keys of rosdep/base.yaml and rosdep/python.yaml with a non-null focal rule;
  - ROS package keys: the packages released in noetic/distribution.yaml.
test/test_rosdep_keys.py checks package.xml against the list, offline.
Usage: scripts/gen_rosdep_keys.py ROSDISTRO_CHECKOUT [OUTPUT]"""
import os
import subprocess
import sys

import yaml


def resolves(rule, os_name, release):
    """True when a rosdep rule gives os_name/release something to install (not null / [])."""
    if not isinstance(rule, dict) or rule.get(os_name) is None:
        return False
    per_os = rule[os_name]
    if isinstance(per_os, dict):
        if release in per_os:
            value = per_os[release]
        elif "*" in per_os:
            value = per_os["*"]
        else:
            # A rule keyed by installer (apt/pip) without releases applies to every release.
            return any(k in per_os for k in ("apt", "pip", "source"))
        return value not in (None, [], {})
    return bool(per_os)


def main():
    src = sys.argv[1]
    out = sys.argv[2] if len(sys.argv) > 2 else os.path.join(
        os.path.dirname(os.path.dirname(os.path.realpath(__file__))), "test", "rosdep_keys_focal.txt")
    commit = subprocess.check_output(["git", "-C", src, "log", "-1", "--format=%H %cs"],
                                     text=True).strip()
    keys = set()
    for rel in ("rosdep/base.yaml", "rosdep/python.yaml"):
        with open(os.path.join(src, rel), encoding="utf-8") as f:
            for key, rule in yaml.safe_load(f).items():
                if resolves(rule, "ubuntu", "focal"):
                    keys.add(key)
    with open(os.path.join(src, "noetic", "distribution.yaml"), encoding="utf-8") as f:
        dist = yaml.safe_load(f)
    for name, repo in dist["repositories"].items():
        release = repo.get("release")
        if release:
            keys.update(release.get("packages", [name]))
    with open(out, "w", encoding="utf-8") as f:
        f.write("# rosdep keys that resolve on Ubuntu 20.04 (focal) for ROS Noetic, one per line.\n")
        f.write("# Source: ros/rosdistro commit %s: rosdep/base.yaml and rosdep/python.yaml\n" % commit)
        f.write("# (keys with a non-null focal rule) and noetic/distribution.yaml (released packages).\n")
        f.write("# Made by: python3 scripts/gen_rosdep_keys.py <rosdistro checkout>\n")
        for key in sorted(keys):
            f.write(key + "\n")
    print("%s: %d keys (rosdistro %s)" % (out, len(keys), commit))


if __name__ == "__main__":
    main()
