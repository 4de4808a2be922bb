"""Packages of raster-oracle: one import package, ``raster_oracle``.

The repository keeps its top-level folders (``oracle/``, ``raster_models/``, ``metrics/``,
``scenes/``, ``reports/``); they are installed as subpackages of ``raster_oracle`` so that no
generic name such as ``metrics`` or ``scenes`` lands at the top level of a user's environment.
Everything else (metadata, dependencies, package data) is in ``pyproject.toml``.
"""

from setuptools import find_packages, setup

FOLDERS = ("oracle", "raster_models", "metrics", "scenes", "reports")

subpackages = find_packages(include=[f"{name}*" for name in FOLDERS])
setup(
    packages=["raster_oracle", *(f"raster_oracle.{name}" for name in subpackages)],
    package_dir={"raster_oracle": "raster_oracle", **{f"raster_oracle.{f}": f for f in FOLDERS}},
)
