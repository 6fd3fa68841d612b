"""Writes JUnit XML from 'suite<TAB>name<TAB>passed|failed|skipped<TAB>message' lines (the jobs
in scripts/sanitize and scripts/multi_host, which are not gtests), so
scripts/count_test_results.py counts them; a skipped case keeps its reason."""
import sys
import xml.etree.ElementTree as ET


def main(tsv: str, out: str) -> None:
    root = ET.Element("testsuites")
    suites = {}
    with open(tsv, encoding="utf-8", errors="replace") as f:
        for line in f:
            parts = line.rstrip("\n").split("\t")
            if len(parts) < 3:
                continue
            suite, name, status = parts[:3]
            message = parts[3] if len(parts) > 3 else ""
            if suite not in suites:
                suites[suite] = ET.SubElement(root, "testsuite", name=suite)
            case = ET.SubElement(suites[suite], "testcase", classname=suite, name=name)
            if status == "skipped":
                ET.SubElement(case, "skipped", message=message[:2000])
            elif status != "passed":
                ET.SubElement(case, "failure", message=message[:2000])
            elif message:
                ET.SubElement(case, "system-out").text = message[:2000]
    ET.ElementTree(root).write(out, encoding="utf-8", xml_declaration=True)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
