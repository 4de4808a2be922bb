"""Coverage an engine can write (issue 43, item 4): an engine's MSAA coverage mask of the
front-most primitive is scored against the reference's ``front_coverage``
(``--coverage-truth front``); an all-ones mask, which scores perfectly against plain
coverage (the ground plane covers every pixel), fails it."""

from __future__ import annotations

import json

import numpy as np
import pytest
from raster_oracle.oracle.cli import main
from raster_oracle.oracle.reference.exr import read_exr, write_exr

SIZE = ["--width", "96", "--height", "54"]


@pytest.fixture(scope="module")
def masks(tmp_path_factory, _backend):
    root = tmp_path_factory.mktemp("cov")
    argv = ["reference", "plate", *SIZE, "--spp", "16", "--channels", "coverage", "--quiet"]
    assert main([*argv, "--out", str(root / "ref")]) == 0
    front = read_exr(root / "ref" / "reference.exr")["front_coverage"]
    write_exr(root / "front.exr", {"coverage": np.asarray(front, np.float32)})
    write_exr(root / "ones.exr", {"coverage": np.ones_like(front, dtype=np.float32)})
    return root


def _edge_rmse(root, tmp_path, name, *extra):
    out = tmp_path / f"{name}{len(extra)}"
    argv = ["score", "plate", *SIZE, "--candidate", str(root / f"{name}.exr"), "--spp", "16"]
    assert main([*argv, "--channel", "coverage", "--quiet", "--out", str(out), *extra]) == 0
    return json.loads((out / "metrics.json").read_text())["coverage_edge_rmse"]


def test_an_all_ones_mask_fails_against_front_coverage(masks, tmp_path):
    front = ["--coverage-truth", "front"]
    # against plain coverage the all-ones mask looks perfect (the finding)
    assert _edge_rmse(masks, tmp_path, "ones") < 0.05
    # against the front-most primitive's coverage it is far off, the correct mask is not
    assert _edge_rmse(masks, tmp_path, "ones", *front) > 0.2
    assert _edge_rmse(masks, tmp_path, "front", *front) < 0.05
