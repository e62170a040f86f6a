#!/usr/bin/env python3
"""Writes a JUnit result file with one skipped test case, so a test that cannot run here (e.g. a
rostest without its data) is counted as skipped, never as passed or silently missing.

Usage: write_skipped_result.py RESULT.xml TEST_NAME REASON
"""
import os
import sys
from xml.sax.saxutils import quoteattr


def write_skipped(path, name, reason):
    """Writes `path`: one suite `name` with one test case skipped for `reason`."""
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    with open(path, "w") as f:
        f.write('<?xml version="1.0" encoding="utf-8"?>\n'
                '<testsuite name=%s tests="1" failures="0" errors="0" skipped="1">\n'
                '  <testcase classname=%s name="skipped">\n'
                '    <skipped message=%s/>\n'
                '  </testcase>\n'
                '</testsuite>\n' % (quoteattr(name), quoteattr(name), quoteattr(reason)))


def main(argv):
    if len(argv) != 4:
        print(__doc__, file=sys.stderr)
        return 2
    write_skipped(argv[1], argv[2], argv[3])
    print("SKIPPED %s: %s" % (argv[2], argv[3]))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
