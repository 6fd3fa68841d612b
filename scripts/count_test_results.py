"""Counts JUnit XML results under a folder and prints 'N passed, N failed'.

A build or runner failure (non-zero status) with no recorded failure still counts as one
failure, so a broken build can never print a clean summary.
"""
import pathlib
import sys
import xml.etree.ElementTree as ET


def main(results_dir: str, runner_status: int) -> int:
    passed = failed = 0
    for path in sorted(pathlib.Path(results_dir).rglob("*.xml")):
        try:
            root = ET.parse(path).getroot()
        except ET.ParseError:
            print(f"unreadable test result: {path}")
            failed += 1
            continue
        for case in root.iter("testcase"):
            problem = case.find("failure")
            if problem is None:
                problem = case.find("error")
            if problem is not None:
                failed += 1
                print(f"FAILED: {case.get('classname')}.{case.get('name')}")
                # What the test said, so that a CI log names the failed check (first lines only).
                said = (problem.get("message") or problem.text or "").strip().splitlines()
                for line in said[:12]:
                    print(f"    {line[:300]}")
            elif case.find("skipped") is not None:
                # Never silently: the reason is printed above the summary line.
                print(f"SKIPPED: {case.get('classname')}.{case.get('name')}: {case.find('skipped').get('message', '')}")
            elif case.get("status", "run") != "notrun":
                passed += 1
    if runner_status != 0 and failed == 0:
        print(f"test runner exited with status {runner_status}")
        failed = 1
    print(f"{passed} passed, {failed} failed")
    return 0 if failed == 0 and passed > 0 else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], int(sys.argv[2])))
