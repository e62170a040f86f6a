#!/usr/bin/env python3
"""Writes one JUnit XML file with one test case, for scripts/test_summary.py.

  sanitize_junit.py FILE SUITE NAME pass|fail MESSAGE
"""
import sys
import xml.etree.ElementTree as ET


def main():
    path, suite, name, status, message = sys.argv[1:6]
    ts = ET.Element("testsuite", name=suite, tests="1",
                    failures="0" if status == "pass" else "1", errors="0")
    case = ET.SubElement(ts, "testcase", classname=suite, name=name)
    if status != "pass":
        ET.SubElement(case, "failure", message=message[:200]).text = message
    elif message:
        ET.SubElement(case, "system-out").text = message
    ET.ElementTree(ts).write(path, encoding="utf-8", xml_declaration=True)


if __name__ == "__main__":
    main()
