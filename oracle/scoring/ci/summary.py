"""A Markdown summary of a scored run (``--summary-md``): what a pull-request comment shows.

The verdict first (the exit code's word), then the first screen: one row per scene with a
failed check, its failed gates by name and its regressions counted (an intended change that
moves 20 metrics of one case is one row, not 20); then every failed check with the same name
as the JUnit case and ``metrics.json``'s ``failed``, with this run's value, the limit or the
baseline's value and both noise floors; then the scenes that could not be scored, the likely
causes found (diagnoses), the metrics not compared with the baseline (named, by scene), and
the passing checks, each with its scene.
"""

from __future__ import annotations

from pathlib import Path

from ....scenes.base.files import atomic_write_bytes
from ....scenes.base.untrusted import escape_markdown

__all__ = ["summary_markdown", "write_summary_md"]


def _num(value) -> str:
    return "—" if value is None else f"{value:.4g}"


def _cell(text: str) -> str:
    """User text (scene, check and file names, messages) in Markdown: every Markdown and
    HTML special escaped, control characters written out, one line (no table, link, image,
    tag or code span can come from it)."""
    return escape_markdown(text)


def summary_markdown(verdicts, *, records=None, report=None) -> str:
    """The Markdown text of ``verdicts`` (one per scene; ``records``: their ``metrics.json``
    records, for the diagnoses; ``report``: the report's path, linked at the end)."""
    verdicts = list(verdicts)
    checks = [(v.scene, c) for v in verdicts for c in v.checks]
    failed = [(s, c) for s, c in checks if not c.passed]
    errors = [(v.scene, n, m) for v in verdicts for n, m in v.errors]
    code = max((v.exit_code for v in verdicts), default=0)
    word = "FAIL" if code else "PASS"
    lines = [
        f"## raster-oracle: {word}",
        "",
        f"{len(failed)} of {len(checks)} checks failed"
        + (f", {len(errors)} input error(s)" if errors else "")
        + f" (exit code {code}).",
        "",
    ]
    if failed:
        lines += _first_screen(failed)
        lines += [
            f"<details><summary>{len(failed)} failed checks</summary>",
            "",
            "| scene | check | now | limit / baseline | noise floor (now / baseline) |",
            "|---|---|---:|---:|---:|",
        ]
        for scene, c in failed:
            against = c.limit if c.kind == "gate" else c.previous
            floors = _num(c.floor) + (f" / {_num(c.previous_floor)}" if c.kind != "gate" else "")
            lines.append(
                f"| {_cell(scene)} | {_cell(c.name)} | {_num(c.value)} | {_num(against)} "
                f"| {floors} |"
            )
        lines += ["", "</details>", ""]
    for scene, name, message in errors:
        lines.append(f"- **{_cell(scene)}** {_cell(name)}: {_cell(message)}")
    if errors:
        lines.append("")
    for rec in records or []:
        for d in (rec or {}).get("diagnoses") or []:
            scene = ((rec.get("reference") or {}).get("scene") or {}).get("name", "?")
            lines.append(f"- likely cause in **{_cell(scene)}**: {_cell(d['message'])}")
    uncompared = [(s, c) for s, c in checks if c.passed and not getattr(c, "compared", True)]
    if uncompared:
        lines += [
            "",
            f"**{len(uncompared)} metric(s) not compared with the baseline** "
            "(`--baseline-strict` fails them):",
            "",
        ]
        lines += [f"- **{_cell(s)}** {_cell(c.line)}" for s, c in uncompared]
    passed = [(s, c) for s, c in checks if c.passed and getattr(c, "compared", True)]
    if passed:
        lines += ["", f"<details><summary>{len(passed)} passing checks</summary>", ""]
        lines += [f"- **{_cell(s)}** {_cell(c.line)}" for s, c in passed]
        lines += ["", "</details>"]
    if report is not None:
        lines += ["", f"Report: {_cell(report)}"]
    return "\n".join(lines).rstrip() + "\n"


def _first_screen(failed) -> list[str]:
    """One row per scene with a failed check: its failed gates by name, its regressions (and
    other baseline checks) counted with their first metrics."""
    scenes: dict[str, list] = {}
    for scene, c in failed:
        scenes.setdefault(scene, []).append(c)
    lines = ["| scene | failed | gates | regressions |", "|---|---:|---|---|"]
    for scene, checks in scenes.items():
        gates = [c.name for c in checks if c.kind == "gate"]
        regressed = [c.metric or c.name for c in checks if c.kind != "gate"]
        shown = ", ".join(regressed[:5]) + (
            f" and {len(regressed) - 5} more" if len(regressed) > 5 else ""
        )
        lines.append(
            f"| {_cell(scene)} | {len(checks)} | {_cell(', '.join(gates)) or '—'} "
            f"| {f'{len(regressed)}: {_cell(shown)}' if regressed else '—'} |"
        )
    return [*lines, ""]


def write_summary_md(path, verdicts, *, records=None, report=None) -> None:
    """Write :func:`summary_markdown` to ``path`` atomically."""
    text = summary_markdown(verdicts, records=records, report=report)
    atomic_write_bytes(Path(path), text.encode("utf-8", "backslashreplace"))
