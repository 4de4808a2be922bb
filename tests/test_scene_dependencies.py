"""Issue 48: a Mitsuba XML scene's files are read only inside its folder, bounded: a
reference to a file outside (absolute, ``..``, a link out) or a file over the limit (a 20 GB
sparse file named by a ``<string>``) is one line and exit 2, before Mitsuba reads anything."""

from __future__ import annotations

import pytest
from raster_oracle.oracle.cli import main
from test_cache import HEAD

#: A plate and a second shape whose ``<string>`` names the file under test.
BODY = '<shape type="rectangle"/><shape type="rectangle"><string name="id" value="{ref}"/></shape>'


def _scene(folder, ref):
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "scene.xml"
    path.write_text(HEAD.format(defaults="", body=BODY.format(ref=ref)))
    return path


def _run(path, tmp_path, capfd):
    out = tmp_path / "o"
    rc = main(["reference", str(path), "--spp", "1", "--quiet", "--no-cache", "--out", str(out)])
    err = capfd.readouterr().err.strip().splitlines()
    assert not out.exists()
    return rc, err


@pytest.mark.parametrize("form", ["absolute", "dotdot", "link"])
def test_a_file_outside_the_scene_folder_is_refused(tmp_path, capfd, form):
    secret = tmp_path / "secret.txt"
    secret.write_text("not the scene's")
    folder = tmp_path / "scene"
    folder.mkdir()
    ref = {"absolute": str(secret), "dotdot": "../secret.txt", "link": "inside.txt"}[form]
    if form == "link":
        (folder / "inside.txt").symlink_to(secret)
    rc, err = _run(_scene(folder, ref), tmp_path, capfd)
    assert rc == 2 and len(err) == 1, err
    assert "outside the scene's folder" in err[0]


def test_a_huge_file_named_by_a_string_is_refused_unread(tmp_path, capfd):
    folder = tmp_path / "scene"
    folder.mkdir()
    with open(folder / "huge.bin", "wb") as f:  # sparse: no disk used
        f.truncate(20 << 30)
    rc, err = _run(_scene(folder, "huge.bin"), tmp_path, capfd)
    assert rc == 2 and len(err) == 1, err
    assert "over the limit" in err[0] and "huge.bin" in err[0]
