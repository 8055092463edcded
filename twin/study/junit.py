"""A check as JUnit XML, the test report format CI systems display (Jenkins, GitLab, GitHub).

One ``testsuite`` per check; one ``testcase`` per sweep point × method × expectation, named by
the expectation and classed ``<scenario>.<method>``, with a ``failure`` that carries the measured
value when it does not hold; with a baseline, one ``testcase`` per metric compared, classed
``<scenario>.<method>.baseline``, failed when it regressed and ``skipped`` when the test could
not decide.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

from twin.io.atomic import write_atomic
from twin.report.display import SIGNIFICANT, percent, plain
from twin.study.check import CheckReport, measured_text


def _suffix(case: str) -> str:
    return f" [{case}]" if case else ""


def junit_xml(report: CheckReport) -> str:
    """The report as a JUnit XML document."""
    suite = ET.Element("testsuite", name=f"twin check {report.scenario}")
    properties = ET.SubElement(suite, "properties")
    for name, value in (("scenario", str(report.source)), ("study", str(report.folder)),
                        ("trials", str(report.trials)), ("baseline", str(report.baseline or ""))):
        ET.SubElement(properties, "property", name=name, value=value)
    failures = skipped = 0
    for result in report.results:
        case = ET.SubElement(suite, "testcase", classname=f"{report.scenario}.{result.method}",
                             name=result.expectation.text + _suffix(result.case))
        if not result.passed:
            failures += 1
            measured = measured_text(result)
            failure = ET.SubElement(case, "failure", type="expectation", message=(
                f"measured {measured}, expected {result.expectation.text}"))
            failure.text = (f"{result.method}: {result.expectation.column} "
                            f"{result.expectation.stat} over {result.trials} trials = {measured}"
                            f", expected {result.expectation.op} {result.expectation.value:g}")
    for comparison in report.comparisons:
        case = ET.SubElement(
            suite, "testcase", classname=f"{report.scenario}.{comparison.method}.baseline",
            name=f"{comparison.column} not worse than the baseline" + _suffix(comparison.case))
        summary = (f"median difference "
                   f"{plain(comparison.median_difference, significant=SIGNIFICANT, sign=True)} "
                   f"({percent(comparison.relative, 1, sign=True)}) over {comparison.trials} "
                   "paired trials, "
                   f"{comparison.changed} changed, p = "
                   + ("n/a" if comparison.p_value is None else f"{comparison.p_value:.3g}"))
        if comparison.verdict == "regression":
            failures += 1
            failure = ET.SubElement(case, "failure", type="regression",
                                    message=f"regression: {summary}")
            failure.text = summary + "; worse most: " + ", ".join(
                f"trial {trial} {difference:+.4g}" for trial, difference in comparison.moved)
        elif comparison.verdict == "inconclusive":
            skipped += 1
            ET.SubElement(case, "skipped", message=f"inconclusive, too few changed trials: "
                          f"{summary}")
    suite.set("tests", str(len(report.results) + len(report.comparisons)))
    suite.set("failures", str(failures))
    suite.set("errors", "0")
    suite.set("skipped", str(skipped))
    root = ET.Element("testsuites", name="twin check", tests=suite.get("tests", "0"),
                      failures=str(failures), errors="0", skipped=str(skipped))
    root.append(suite)
    ET.indent(root)
    return ET.tostring(root, encoding="unicode", xml_declaration=True) + "\n"


def write_junit(path: str | Path, report: CheckReport) -> None:
    """Write :func:`junit_xml` of ``report`` to ``path`` atomically."""
    write_atomic(path, junit_xml(report))
