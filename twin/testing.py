"""Regression tests against the twin's ground truth, for your own test suite.

A pytest test that fails when LM stops recovering the flange is three lines::

    from twin.testing import check

    def test_lm_recovers_the_flange(tmp_path):
        report = check("scenarios/geometric_irb120.toml", tmp_path, trials=5, methods=["lm"])
        assert report.passed, report.text

:func:`check` runs (or resumes) the scenario's study as `twin study` does, evaluates the
scenario's ``[expect]`` table (or ``expect=``, a file or a mapping such as
``{"lm": ["crlb_ratio median <= 1.2"]}``), and with ``baseline=`` compares every metric the
expectations name with an earlier study, trial by trial. The :class:`CheckReport` holds each
expectation's measured value and verdict; ``report.text`` is what `twin check` prints.
See docs/studies.md, "Checks".
"""

from twin.study.baseline import Comparison
from twin.study.check import CheckReport, ExpectationResult, check
from twin.study.expect import Expectation
from twin.study.junit import junit_xml, write_junit

__all__ = ["CheckReport", "Comparison", "Expectation", "ExpectationResult", "check",
           "junit_xml", "write_junit"]
