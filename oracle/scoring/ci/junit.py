"""The checks of scored runs as JUnit XML: one ``<testcase>`` per scene x check."""

from __future__ import annotations

import xml.etree.ElementTree as ET

from ....scenes.base.files import atomic_write_bytes
from .checks import Check

__all__ = ["junit_xml", "write_junit"]


def _properties(case, check: Check) -> None:
    """The check's numbers as JUnit ``<property>`` entries (passing cases carry them too, so
    a CI dashboard can chart a metric's history)."""
    values = {
        "metric": check.metric,
        "kind": "regression" if check.kind == "baseline" else check.kind,
        "value": check.value,
        "limit": check.limit,
        "noise_floor": check.floor,
        "previous": check.previous,
        "previous_noise_floor": check.previous_floor,
    }
    props = ET.SubElement(case, "properties")
    for key, value in values.items():
        if value is not None:
            text = value if isinstance(value, str) else repr(float(value))
            ET.SubElement(props, "property", {"name": key, "value": text})


def junit_xml(verdicts) -> bytes:
    """JUnit XML of the checks of ``verdicts``: one ``<testsuite>`` with one ``<testcase>`` per
    scene x check (classname = the scene, name = the check's name, its numbers as
    properties), a ``<failure>`` holding the line of a failed one, a ``<skipped>`` holding
    the line of a baseline check that could not compare (``Check.compared``; it fails under
    ``--baseline-strict``), and an ``<error>`` case per scene that could not be scored
    (``Verdict.errors``)."""
    checks = [(v.scene, c) for v in verdicts for c in v.checks]
    errors = [(v.scene, e) for v in verdicts for e in getattr(v, "errors", [])]
    n_fail = sum(not c.passed for _, c in checks)
    n_skip = sum(c.passed and not getattr(c, "compared", True) for _, c in checks)
    counts = {
        "tests": str(len(checks) + len(errors)),
        "failures": str(n_fail),
        "errors": str(len(errors)),
        "skipped": str(n_skip),
    }
    root = ET.Element("testsuites", {"name": "raster-oracle", **counts})
    suite = ET.SubElement(root, "testsuite", {"name": "raster-oracle score", **counts})
    for scene, c in checks:
        case = ET.SubElement(suite, "testcase", {"classname": scene, "name": c.name})
        _properties(case, c)
        if c.passed and not getattr(c, "compared", True):
            # a baseline check that could not compare: named, not silently passed
            skipped = ET.SubElement(case, "skipped", {"message": c.line})
            skipped.text = c.line
        if not c.passed:
            kind = "regression" if c.kind == "baseline" else "threshold"
            failure = ET.SubElement(case, "failure", {"message": c.line, "type": kind})
            failure.text = c.line
    for scene, (name, message) in errors:
        case = ET.SubElement(suite, "testcase", {"classname": scene, "name": name})
        error = ET.SubElement(case, "error", {"message": message, "type": "input"})
        error.text = message
    _xml_safe(root)
    ET.indent(root)
    return ET.tostring(root, encoding="utf-8", xml_declaration=True) + b"\n"


def _xml_safe(root) -> None:
    """Every attribute and text of ``root`` with only the characters XML allows (user text:
    scene and check names, messages; a NUL or an escape character would make it unreadable)."""
    from ....scenes.base.untrusted import xml_text

    for el in root.iter():
        el.attrib.update({k: xml_text(v) for k, v in el.attrib.items()})
        if el.text is not None:
            el.text = xml_text(el.text)


def write_junit(path, verdicts) -> None:
    """Write :func:`junit_xml` of ``verdicts`` to ``path`` atomically."""
    atomic_write_bytes(path, junit_xml(verdicts))
