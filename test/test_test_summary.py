"""scripts/test_summary.py, the closing line of every test run (and of CI): counts passed,
failed and skipped cases in JUnit XML, prints each failure's reason (CI logs keep only their
tail), and exits non-zero on a failure, an unreadable result file or no test at all."""
import os
import subprocess
import sys
import tempfile
import unittest

ROOT = os.path.dirname(os.path.dirname(os.path.realpath(__file__)))
SCRIPT = os.path.join(ROOT, "scripts", "test_summary.py")

PASS = '<testcase classname="a" name="ok"/>'
SKIP = '<testcase classname="a" name="later"><skipped message="no data"/></testcase>'
NOTRUN = '<testcase classname="a" name="disabled" status="notrun"/>'
FAIL = ('<testcase classname="fuzz" name="normal_60s"><failure message="timeout: input took '
        '61 s">log</failure></testcase>')
ERROR = '<testcase classname="r" name="launch"><error>process died\n  exit 1</error></testcase>'


def run(files):
    """Writes {name: xml body} under a temporary folder; returns (exit code, stdout)."""
    with tempfile.TemporaryDirectory() as d:
        for name, body in files.items():
            os.makedirs(os.path.dirname(os.path.join(d, name)), exist_ok=True)
            with open(os.path.join(d, name), "w") as f:
                f.write(body)
        p = subprocess.run([sys.executable, SCRIPT, d], stdout=subprocess.PIPE,
                           universal_newlines=True)
        return p.returncode, p.stdout


def suite(*cases):
    return "<testsuite>%s</testsuite>" % "".join(cases)


class TestSummary(unittest.TestCase):
    def test_counts_and_green(self):
        rc, out = run({"a.xml": suite(PASS, PASS, SKIP, NOTRUN), "sub/b.xml": suite(PASS)})
        self.assertEqual(rc, 0, out)
        self.assertIn("Summary: 3 passed, 0 failed, 2 skipped", out)
        self.assertNotIn("FAILED", out)

    def test_failure_and_error_print_their_reason(self):
        rc, out = run({"fuzz.xml": suite(PASS, FAIL), "r.xml": suite(ERROR)})
        self.assertEqual(rc, 1)
        self.assertIn("Summary: 1 passed, 2 failed, 0 skipped", out)
        self.assertIn("FAILED: fuzz.xml fuzz.normal_60s", out)
        self.assertIn("reason: timeout: input took 61 s", out)  # the message attribute
        self.assertIn("reason: process died exit 1", out)  # the text, whitespace folded

    def test_long_reason_is_cut(self):
        long = '<testcase classname="a" name="b"><failure message="%s"/></testcase>' % ("x" * 2000)
        rc, out = run({"a.xml": suite(long)})
        self.assertEqual(rc, 1)
        reason = [l for l in out.splitlines() if l.startswith("  reason: ")][0]
        self.assertEqual(len(reason), len("  reason: ") + 600)

    def test_unreadable_file_fails(self):
        rc, out = run({"a.xml": suite(PASS), "broken.xml": "<testsuite><testcase"})
        self.assertEqual(rc, 1)
        self.assertIn("FAILED: unreadable result file", out)
        self.assertIn("Summary: 1 passed, 1 failed, 0 skipped", out)

    def test_nothing_ran_is_not_green(self):
        self.assertEqual(run({})[0], 1)
        self.assertEqual(run({"a.xml": suite(SKIP)})[0], 1)  # skips alone are no pass
        self.assertEqual(run({"notes.txt": "no xml"})[0], 1)


if __name__ == "__main__":
    unittest.main()
