"""The public faces are declared once and held equal: the API's names (one list,
``raster_oracle.api_names.API_NAMES``: the package's lazy names and ``api.__all__``), the
scene options (``scenes.loader.LoadOptions``: ``load``, ``load_input``, ``load_scene`` and the
API page), the families the registry's docstrings name, and the modules the README's layout
names."""

from __future__ import annotations

import ast
import inspect
import re
import subprocess
import sys
from dataclasses import fields
from pathlib import Path

import pytest
from raster_oracle.raster_models import registry
from raster_oracle.scenes.inputs import load_input
from raster_oracle.scenes.loader import LoadOptions, load

import raster_oracle as ro
from raster_oracle import api
from raster_oracle.api_names import API_NAMES

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("scenes", "raster_models", "metrics", "reports", "oracle", "raster_oracle")


def test_lazy_names_are_the_one_list():
    assert len(set(API_NAMES)) == len(API_NAMES)
    assert set(ro.__all__) == {"__version__", *API_NAMES}
    assert list(api.__all__) == list(API_NAMES)
    assert set(API_NAMES) <= set(dir(ro))
    for name in API_NAMES:
        assert getattr(ro, name) is getattr(api, name), name
    with pytest.raises(AttributeError):
        ro.no_such_function  # noqa: B018


def test_every_public_function_of_api_is_listed():
    """A function or class ``api.py`` defines without an underscore is an API name (a new
    one cannot be forgotten in the list)."""
    tree = ast.parse((ROOT / "raster_oracle" / "api.py").read_text())
    defined = {
        n.name
        for n in tree.body
        if isinstance(n, ast.FunctionDef | ast.ClassDef) and not n.name.startswith("_")
    }
    assert defined <= set(API_NAMES), sorted(defined - set(API_NAMES))


def test_import_stays_cheap():
    """``import raster_oracle`` loads no API module (and so no Mitsuba)."""
    code = "import sys, raster_oracle; print('raster_oracle.api' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_scene_options_are_declared_once():
    names = [f.name for f in fields(LoadOptions)]
    for func in (load, load_input, ro.load_scene):
        params = inspect.signature(func).parameters
        assert list(params)[1:] == names, func.__qualname__
        assert all(params[n].default == getattr(LoadOptions(), n) for n in names)
    page = (ROOT / "docs" / "python-api.md").read_text()
    row = re.search(r"`ro\.load_scene\(scene, \*, ([^)]*)\)`", page)
    assert row is not None and row.group(1).split(", ") == names


def test_an_unknown_scene_option_is_named():
    with pytest.raises(ro.InputError, match="unknown scene option widht; the options are width"):
        ro.load_scene("plate", widht=32)


def test_registry_docstrings_name_every_family():
    for text in (registry.Technique.__doc__, registry.family_of.__doc__):
        missing = [f for f in registry.FAMILIES if f"``{f}``" not in text]
        assert not missing, missing


def _modules() -> list[Path]:
    return [p for top in PACKAGES for p in sorted((ROOT / top).rglob("*.py"))]


def test_readme_layout_names_every_module():
    text = (ROOT / "README.md").read_text()
    layout = text[text.index("## Layout") :]
    words = set(re.findall(r"[A-Za-z_][A-Za-z0-9_]*", layout))
    missing = []
    for p in _modules():
        name = p.parent.name if p.name == "__init__.py" else p.stem
        if name not in words:
            missing.append(str(p.relative_to(ROOT)))
    assert not missing, f"README.md's layout does not name: {', '.join(missing)}"
