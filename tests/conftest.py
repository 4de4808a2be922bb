"""Shared fixtures: one backend for the whole run, a private reference cache."""

from __future__ import annotations

import os

import pytest


@pytest.fixture(scope="session", autouse=True)
def _backend(tmp_path_factory):
    """Select the backend once (as the CLI does) and keep the user's cache untouched."""
    os.environ["RASTER_ORACLE_CACHE"] = str(tmp_path_factory.mktemp("cache"))
    from raster_oracle.scenes import backend

    return backend.select()


@pytest.fixture(scope="session")
def mi(_backend):
    from raster_oracle.scenes import backend

    return backend.mitsuba()
