#!/usr/bin/env python3
"""Counts test cases in catkin's JUnit XML results and prints one closing summary line.

Exits 1 when any case failed or errored, or when no test ran at all (a build or launch error
that produced no result must not pass as green)."""
import os
import sys
import xml.etree.ElementTree as ET


def main():
    root = sys.argv[1]
    passed = failed = skipped = 0
    bad_files = []
    for dirpath, _, files in os.walk(root):
        for name in sorted(files):
            if not name.endswith(".xml"):
                continue
            path = os.path.join(dirpath, name)
            try:
                tree = ET.parse(path)
            except ET.ParseError:
                bad_files.append(path)
                continue
            for case in tree.iter("testcase"):
                if case.find("failure") is not None or case.find("error") is not None:
                    failed += 1
                    print("FAILED: %s %s.%s" % (name, case.get("classname"), case.get("name")))
                    # The reason, short: CI logs keep only their tail, where this summary is.
                    node = case.find("failure")
                    if node is None:
                        node = case.find("error")
                    why = " ".join((node.get("message") or node.text or "").split())
                    if why:
                        print("  reason: %s" % why[:600])
                elif case.find("skipped") is not None or case.get("result") == "skipped" \
                        or case.get("status") == "notrun":  # gtest 1.10 (focal) marks it so
                    skipped += 1
                else:
                    passed += 1
    for path in bad_files:
        print("FAILED: unreadable result file %s" % path)
    failed += len(bad_files)
    total = passed + failed + skipped
    print("Summary: %d passed, %d failed, %d skipped" % (passed, failed, skipped))
    return 0 if failed == 0 and total > 0 and passed > 0 else 1


if __name__ == "__main__":
    sys.exit(main())
