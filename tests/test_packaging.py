"""The installed package is one namespaced import package, ``raster_oracle``: a wheel of the
checkout holds nothing else at the top level, its subpackages import from an install outside
the checkout, and the generic names (``metrics``, ``scenes``, ``oracle``) do not import."""

from __future__ import annotations

import importlib.util
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

#: about 25 s: a wheel build and an install in subprocesses
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parent.parent
#: What setup.py needs to build the wheel (copied, so the build leaves the checkout clean).
SOURCES = (
    "setup.py",
    "pyproject.toml",
    "README.md",
    "LICENSE",
    "raster_oracle",
    "oracle",
    "raster_models",
    "metrics",
    "scenes",
    "reports",
)


def _builds_wheels_in_place() -> bool:
    """Whether this environment can build a wheel without build isolation: setuptools >= 70.1
    has ``bdist_wheel`` itself, older ones need the ``wheel`` package."""
    import setuptools

    major, minor = (int(p) for p in setuptools.__version__.split(".")[:2])
    return (major, minor) >= (70, 1) or importlib.util.find_spec("wheel") is not None


def _run(cmd, **kw):
    done = subprocess.run(cmd, capture_output=True, text=True, **kw)
    assert done.returncode == 0, f"{cmd} failed:\n{done.stdout}\n{done.stderr}"
    return done


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """Build a wheel of a copy of the checkout (no dependencies) and
    install it with ``pip install --no-deps --target``; returns (wheel, target)."""
    tmp = tmp_path_factory.mktemp("packaging")
    src = tmp / "src"
    src.mkdir()
    for name in SOURCES:
        path = ROOT / name
        if path.is_dir():
            shutil.copytree(path, src / name, ignore=shutil.ignore_patterns("__pycache__"))
        else:
            shutil.copy2(path, src / name)
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check", "--no-input"]
    # without build isolation where the environment can build wheels; else (a venv without
    # the `wheel` package) pip fetches the build requirements from its configured index
    flags = ["--no-build-isolation"] if _builds_wheels_in_place() else []
    _run([*pip, "wheel", "--no-deps", *flags, "-w", str(tmp / "dist"), "."], cwd=src)
    (wheel,) = (tmp / "dist").glob("raster_oracle-*.whl")
    target = tmp / "site"
    _run([*pip, "install", "--no-deps", "--no-index", "--target", str(target), str(wheel)])
    return wheel, target


def test_wheel_holds_only_raster_oracle(installed):
    wheel, _ = installed
    with zipfile.ZipFile(wheel) as zf:
        tops = {name.split("/", 1)[0] for name in zf.namelist()}
        names = zf.namelist()
    assert {t for t in tops if not t.endswith(".dist-info")} == {"raster_oracle"}
    # the subpackages and their data files are inside it
    for path in (
        "raster_oracle/oracle/cli/app.py",
        "raster_oracle/metrics/__init__.py",
        "raster_oracle/api.py",
        "raster_oracle/oracle/specs/default.toml",
    ):
        assert path in names


def _python(code: str, target: Path, cwd: Path) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["PYTHONPATH"] = str(target)
    return subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=cwd
    )


def test_installed_package_imports_outside_the_checkout(installed, tmp_path):
    _, target = installed
    done = _python(
        "import raster_oracle, raster_oracle.oracle.cli, raster_oracle.api as a; "
        "print(raster_oracle.__file__); print(raster_oracle.oracle.cli.__file__); "
        "print(raster_oracle.score_image is a.score_image)",
        target,
        tmp_path,
    )
    assert done.returncode == 0, done.stderr
    lines = done.stdout.split()
    assert all(line.startswith(str(target)) for line in lines[:2]), lines
    assert lines[2] == "True"


@pytest.mark.parametrize("name", ["metrics", "scenes", "oracle", "reports", "raster_models"])
def test_generic_names_are_not_installed(installed, tmp_path, name):
    _, target = installed
    assert not (target / name).exists()
    done = _python(f"import {name}", target, tmp_path)
    assert done.returncode != 0 and "ModuleNotFoundError" in done.stderr
