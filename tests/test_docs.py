"""The documentation cannot rot: its Python examples run, its CLI reference names every
command and option the parser has, its metric reference names every metric key, its links
resolve, and the README stays short with the two quick-start commands."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"


def python_blocks(path: Path) -> list[str]:
    """The ```python blocks of a Markdown file, in order."""
    return re.findall(r"^```python\n(.*?)^```", path.read_text(), flags=re.S | re.M)


def test_python_api_examples_run(tmp_path, monkeypatch, capsys):
    """Every ```python block of docs/python-api.md runs, in order, in one namespace, in an
    empty folder (tiny sizes and spp keep it quick)."""
    blocks = python_blocks(DOCS / "python-api.md")
    assert len(blocks) >= 7
    monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": "__docs__"}
    for i, code in enumerate(blocks):
        try:
            exec(compile(code, f"docs/python-api.md block {i}", "exec"), namespace)
        except Exception as exc:  # name the block that broke
            pytest.fail(f"docs/python-api.md block {i} raised {type(exc).__name__}: {exc}")
    out = capsys.readouterr().out
    assert "candidate is 10x10, the reference is 80x45" in out
    assert (tmp_path / "score" / "metrics.json").is_file()
    assert (tmp_path / "junit.xml").is_file()


def _parser_options() -> dict[str, list[str]]:
    from raster_oracle.oracle.cli.app import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    out = {"": [o for a in parser._actions for o in a.option_strings if o not in ("-h", "--help")]}
    for name, p in sub.choices.items():
        out[name] = [o for a in p._actions for o in a.option_strings if o not in ("-h", "--help")]
    return out


def test_cli_reference_names_every_command_and_option():
    text = (DOCS / "cli.md").read_text()
    missing = []
    for command, options in _parser_options().items():
        if command and f"`raster-oracle {command}" not in text:
            missing.append(command)
        missing += [
            f"{command} {o}" for o in options if not re.search(rf"(?<![\w-]){o}(?![\w-])", text)
        ]
    assert not missing, f"docs/cli.md does not document: {', '.join(missing)}"


def test_cli_reference_gives_exit_codes():
    text = (DOCS / "cli.md").read_text()
    for code in ("| 0 |", "| 1 |", "| 2 |"):
        assert code in text


def test_metrics_reference_names_every_metric():
    from raster_oracle.oracle.scoring.score import METRIC_KEYS

    text = (DOCS / "metrics.md").read_text()
    missing = [k for k in METRIC_KEYS if f"`{k}`" not in text]
    assert not missing, f"docs/metrics.md does not describe: {', '.join(missing)}"


@pytest.mark.parametrize("page", ["README.md", *(f"docs/{p.name}" for p in DOCS.glob("*.md"))])
def test_links_resolve(page):
    path = ROOT / page
    text = path.read_text()
    bad = []
    for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text):
        if "://" in target:
            continue
        if not (path.parent / target).exists():
            bad.append(target)
    assert not bad, f"{page} links to missing files: {bad}"


def test_readme_is_short_and_keeps_the_quick_start():
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) < 170
    assert "bin/main.sh     # the main job" in text
    assert "bin/test.sh     # the whole test suite" in text
    for flag in ("export", "--fail-above", "--fail-below", "--baseline", "--junit"):
        assert flag in text


def test_readme_names_the_set_up_script_and_conventions_one_oracle_version():
    """Issue 43 item 8: the quick start names `bin/setup.sh`; docs/conventions.md gives the
    oracle version the cache uses, once."""
    from raster_oracle.oracle.reference.cache import ORACLE_VERSION

    assert "bin/setup.sh" in (ROOT / "README.md").read_text()
    text = (DOCS / "conventions.md").read_text()
    versions = set(re.findall(r"[Oo]racle version \(?(\d+)\)?", text))
    assert versions == {ORACLE_VERSION}, versions
