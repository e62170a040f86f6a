#!/usr/bin/env python3
"""Writes a JUnit result file with one test case, so CI steps outside catkin's test runners (and
tests that cannot run here, e.g. a rostest without its data) are counted by catkin_test_results
and scripts/test_summary.py: skipped is counted as skipped, never as passed.

Usage: junit_result.py RESULT.xml SUITE CASE passed|failed|skipped MESSAGE...
"""
import os
import sys
from xml.sax.saxutils import escape, quoteattr


def write_result(path, suite, case, status, message):
    """Writes `path`: suite `suite` with the one test case `case` in state `status`."""
    if status not in ("passed", "failed", "skipped"):
        raise ValueError("status must be passed, failed or skipped, not %r" % status)
    body = ""
    if status == "failed":
        body = "    <failure message=%s>%s</failure>\n" % (quoteattr(message.splitlines()[0]
                                                                 if message else "failed"),
                                                        escape(message))
    elif status == "skipped":
        body = "    <skipped message=%s/>\n" % quoteattr(message)
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    with open(path, "w") as f:
        f.write('<?xml version="1.0" encoding="utf-8"?>\n'
                '<testsuite name=%s tests="1" failures="%d" errors="0" skipped="%d">\n'
                '  <testcase classname=%s name=%s>\n%s  </testcase>\n'
                '</testsuite>\n' % (quoteattr(suite), status == "failed", status == "skipped",
                                    quoteattr(suite), quoteattr(case), body))


def main(argv):
    if len(argv) < 6:
        print(__doc__, file=sys.stderr)
        return 2
    # The message may arrive split into words (catkin's run_tests.py runs a shell command line).
    message = " ".join(argv[5:])
    write_result(argv[1], argv[2], argv[3], argv[4], message)
    print("%s %s.%s: %s" % (argv[4].upper(), argv[2], argv[3], message))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
