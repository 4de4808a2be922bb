"""Issue 48: an output option naming an input is exit 2 before any work (links followed),
and a score-folder run appears whole: a failing case leaves --out as it was, and a reused
--out never keeps an earlier run's case beside new results."""

from __future__ import annotations

import json

import numpy as np
import pytest
from raster_oracle.oracle.cli import main
from raster_oracle.oracle.reference.exr import write_exr

W, H = 32, 18


@pytest.fixture(scope="module")
def exports(tmp_path_factory):
    root = tmp_path_factory.mktemp("exports")
    for scene in ("plate", "thin"):
        argv = ["export", scene, "--width", str(W), "--height", str(H)]
        assert main([*argv, "--out", str(root / scene)]) == 0
    return root


def _candidate(path, value=1.0):
    image = np.full((H, W), value, np.float32)
    write_exr(path, {"visibility": image})
    return path


def _refused(argv, capfd, *files):
    before = {f: f.read_bytes() for f in files}
    assert main(argv) == 2
    err = capfd.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "would destroy it" in err[0], err
    for f, data in before.items():
        assert f.read_bytes() == data, f


def test_score_outputs_naming_an_input_are_refused(exports, tmp_path, capfd):
    cand = _candidate(tmp_path / "cand.exr")
    link = tmp_path / "link.xml"
    link.symlink_to(cand)
    baseline = tmp_path / "base" / "metrics.json"
    baseline.parent.mkdir()
    argv = ["score", str(exports / "plate"), "--candidate", str(cand), "--spp", "1"]
    argv += ["--quiet", "--no-cache", "--out", str(tmp_path / "o")]
    assert main(argv) == 0
    baseline.write_bytes((tmp_path / "o" / "metrics.json").read_bytes())
    scene_xml = exports / "plate" / "scene.xml"
    _refused([*argv, "--junit", str(cand)], capfd, cand)
    _refused([*argv, "--junit", str(link)], capfd, cand)  # through a link
    _refused([*argv, "--summary-md", str(scene_xml)], capfd, scene_xml)
    _refused([*argv, "--junit", str(baseline), "--baseline", str(baseline)], capfd, baseline)


def test_score_folder_outputs_naming_an_input_are_refused(exports, tmp_path, capfd):
    root = tmp_path / "root"
    root.mkdir()
    image = _candidate(root / "plate.exr")
    manifest = tmp_path / "ci.toml"
    manifest.write_text(f'[scenes.plate]\nscene = "{exports / "plate"}"\nfile = "plate.exr"\n')
    argv = ["score-folder", str(root), "--spp", "1", "--quiet", "--no-cache"]
    argv += ["--out", str(tmp_path / "o")]
    _refused([*argv, "--exports", str(exports), "--junit", str(image)], capfd, image)
    _refused([*argv, "--manifest", str(manifest), "--summary-md", str(manifest)], capfd, manifest)
    assert not (tmp_path / "o").exists()


def _folder_run(exports, root, out, **images):
    root.mkdir()
    for scene, value in images.items():
        _candidate(root / f"{scene}.exr", value)
    argv = ["score-folder", str(root), "--exports", str(exports), "--spp", "1"]
    return main([*argv, "--quiet", "--no-cache", "--out", str(out)])


def _snapshot(out):
    return {p.relative_to(out): p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()}


def test_score_folder_output_appears_whole(exports, tmp_path):
    out = tmp_path / "out"
    assert _folder_run(exports, tmp_path / "r1", out, plate=1.0, thin=1.0) in (0, 1)
    assert (out / "plate").is_dir() and (out / "thin").is_dir()
    # a reused --out: the earlier run's case that this run does not score is gone with it
    assert _folder_run(exports, tmp_path / "r2", out, thin=0.0) in (0, 1)
    record = json.loads((out / "metrics.json").read_text())
    assert list(record["scenes"]) == ["thin"]
    assert sorted(p.name for p in out.iterdir()) == [
        "metrics.json",
        "report.html",
        "report.json",
        "thin",
    ]
    before = _snapshot(out)
    # a NaN in the second case: exit 2 and the output as it was (no first case written)
    assert _folder_run(exports, tmp_path / "r3", out, plate=1.0, thin=float("nan")) == 2
    assert _snapshot(out) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out", "r1", "r2", "r3"]


def test_score_folder_checks_every_candidate_before_scoring_any(
    exports, tmp_path, capfd, monkeypatch
):
    """Issue 48: a NaN in the second case was found after the first case was scored."""
    from raster_oracle.oracle.scoring import to_folder

    def never(*_a, **_k):
        raise AssertionError("a case was scored before every candidate was checked")

    monkeypatch.setattr(to_folder, "score_to_folder", never)
    out = tmp_path / "out"
    assert _folder_run(exports, tmp_path / "r", out, plate=1.0, thin=float("nan")) == 2
    err = capfd.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "case thin" in err[0] and "NaN" in err[0], err
    assert not out.exists()
