"""Issue 48's option items: ``--expect`` takes a list value as ``--set`` does, a manifest
error names the scene's key path when it has no channels table, and score-folder's size
advice names no option it does not take."""

from __future__ import annotations

import numpy as np
import pytest
from raster_oracle.oracle.cli import main
from raster_oracle.oracle.reference.exr import write_exr
from raster_oracle.oracle.scoring.conformance import parse_expect
from raster_oracle.oracle.scoring.inputs.manifest import ManifestError, read_manifest

from raster_oracle import raster_models


def test_expect_takes_the_list_set_takes():
    text = "split=manual,splits=0.1,0.3,0.6,1.0"
    technique, params = parse_expect(f"csm:{text}")
    assert technique == "csm"
    assert params == raster_models.parse_params("csm", ["split=manual", "splits=0.1,0.3,0.6,1.0"])
    assert tuple(params["splits"]) == (0.1, 0.3, 0.6, 1.0)


def test_a_manifest_error_without_channels_names_the_scene_key(tmp_path):
    path = tmp_path / "ci.toml"
    path.write_text('[scenes.plate]\ntransfer = "gamma2.4"\n')
    with pytest.raises(ManifestError) as info:
        read_manifest(path)
    assert "[scenes.plate].transfer" in str(info.value) and "None" not in str(info.value)


def test_score_folder_size_advice_names_no_width_option(tmp_path, capfd):
    assert (
        main(
            [
                "export",
                "plate",
                "--width",
                "32",
                "--height",
                "18",
                "--out",
                str(tmp_path / "e" / "plate"),
            ]
        )
        == 0
    )
    root = tmp_path / "root"
    root.mkdir()
    write_exr(root / "plate.exr", {"visibility": np.ones((12, 16), np.float32)})
    capfd.readouterr()
    argv = ["score-folder", str(root), "--exports", str(tmp_path / "e"), "--spp", "1"]
    assert main([*argv, "--quiet", "--no-cache", "--out", str(tmp_path / "o")]) == 2
    err = capfd.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "candidate is 16x12, the reference is 32x18" in err[0], err
    assert "--width" not in err[0]
