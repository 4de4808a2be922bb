"""Every gate comparable against a baseline (issue 43, item 1): the conformance metrics,
which have no noise floor, compare with a documented default tolerance and honour
--baseline-tolerance; a metric that cannot be compared is named in the verdict lines, JUnit
and Markdown, and --baseline-strict fails it."""

from __future__ import annotations

import xml.etree.ElementTree as ET

from raster_oracle.oracle.scoring.ci.junit import junit_xml
from raster_oracle.oracle.scoring.ci.regression import (
    DETERMINISTIC_TOLERANCES,
    BaselineOptions,
    compare_baseline,
)
from raster_oracle.oracle.scoring.ci.summary import summary_markdown

SCENE = {"name": "plate", "resolution": [320, 180], "light_index": 0}
KEYS = ("conformance_misclassified_fraction", "conformance_edge_displacement_px")


def _record(misclassified, edges, **extra):
    return {
        "channel": "visibility",
        "reference": {"scene": SCENE},
        "conformance_misclassified_fraction": misclassified,
        "conformance_edge_displacement_px": edges,
        "noise_floor": {},
        **extra,
    }


def test_a_one_texel_fault_after_baseline_accept_is_a_regression():
    accepted = _record(0.0, 0.006)
    # the numbers: a one-texel lookup fault, 0.00476 misclassified, edges 1.63 px
    faulty = _record(0.00476, 1.63)
    verdict = compare_baseline(faulty, accepted, options=BaselineOptions(KEYS))
    assert verdict.exit_code == 1
    assert verdict.failed == [f"baseline {k}" for k in KEYS]
    assert "tolerance 0.05" in verdict.checks[1].line
    # a correct engine's float32 wobble stays within the default tolerance
    again = compare_baseline(_record(2e-5, 0.02), accepted, options=BaselineOptions(KEYS))
    assert again.exit_code == 0 and all(c.compared for c in again.checks)
    # --baseline-tolerance is honoured: a looser one lets the edges through
    loose = BaselineOptions(KEYS, {KEYS[1]: (2.0, False)})
    assert compare_baseline(faulty, accepted, options=loose).failed == [f"baseline {KEYS[0]}"]
    assert DETERMINISTIC_TOLERANCES[KEYS[1]] == 0.05


def test_an_uncomparable_metric_is_named_everywhere_and_strict_fails_it():
    accepted = _record(0.0, 0.006, flip_mean=0.01, noise_floor={"flip_mean": 0.001})
    now = _record(0.0, 0.006, flip_mean=0.01)  # this run has no noise floor of flip_mean
    options = BaselineOptions((*KEYS, "flip_mean"))
    verdict = compare_baseline(now, accepted, options=options)
    assert verdict.exit_code == 0
    (named,) = [c for c in verdict.checks if not c.compared]
    assert named.metric == "flip_mean" and "NOT COMPARED baseline flip_mean" in named.line
    assert named.line in verdict.lines
    suite = next(ET.fromstring(junit_xml([verdict])).iter("testsuite"))
    assert suite.get("skipped") == "1"
    skipped = [c for c in suite.iter("testcase") if c.find("skipped") is not None]
    assert [c.get("name") for c in skipped] == ["baseline flip_mean"]
    md = summary_markdown([verdict])
    assert "1 metric(s) not compared with the baseline" in md and "flip\\_mean" in md
    strict = compare_baseline(now, accepted, options=BaselineOptions(options.metrics, {}, True))
    assert strict.exit_code == 1 and strict.failed == ["baseline flip_mean"]
    # a gated metric missing from one run is named too
    gone = compare_baseline(_record(0.0, None), accepted, options=BaselineOptions(KEYS))
    assert [c.compared for c in gone.checks] == [True, False]


def test_passing_checks_in_the_markdown_name_their_case():
    verdict = compare_baseline(
        _record(0.0, 0.006), _record(0.0, 0.006), options=BaselineOptions(KEYS)
    )
    md = summary_markdown([verdict])
    assert "- **plate** PASS baseline conformance" in md


def test_an_ssim_floor_below_one_does_not_print_as_one():
    from raster_oracle.oracle.scoring.ci.checks import format_number

    assert format_number(0.99996) == "0.99996" and format_number(1.0) == "1"
    assert format_number(0.9991) == "0.9991" and format_number(0.02) == "0.02"
