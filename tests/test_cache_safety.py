"""Issue 48: the reference cache touches only what it wrote.

A cache folder that holds foreign files (a project's ``.git``, notes, a link to another
folder) is skipped with one line and nothing in it or behind its links is touched; inside
a marked cache, links are never followed and a folder holding foreign files is never
removed; damaged entries (a record that is not a JSON object, an image of the wrong size,
all with consistent checksums) are rendered again; a cache that cannot be made is skipped.
"""

from __future__ import annotations

import hashlib
import json
import os
import time

import numpy as np
from raster_oracle.oracle.cli import main
from raster_oracle.oracle.reference import cache as cache_mod
from raster_oracle.oracle.reference.exr import write_exr

SMALL = ["--width", "16", "--height", "12", "--spp", "1", "--quiet"]
OLD = time.time() - 10 * cache_mod.STALE_SECONDS


def _decoys(folder):
    """Files a careless housekeeper would delete; returns ``{path: bytes}``."""
    files = {
        folder / ".git" / "HEAD": b"ref: refs/heads/main\n",
        folder / "notes" / ".draft.md": b"draft\n",
        folder / "ab" / ".deadbeef.1@host.x" / "notes.txt": b"mine\n",
    }
    for path, data in files.items():
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
    return files


def _outside(tmp_path):
    outside = tmp_path / "home"
    files = {outside / ".profile": b"PATH=x\n", outside / ".ssh" / "id_ed25519": b"key\n"}
    for path, data in files.items():
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
    return outside, files


def _age(root):
    for dirpath, dirnames, filenames in os.walk(root):
        for name in dirnames + filenames:
            os.utime(os.path.join(dirpath, name), (OLD, OLD), follow_symlinks=False)


def _survive(files):
    for path, data in files.items():
        assert path.read_bytes() == data, path


def test_a_folder_of_foreign_files_is_skipped_and_nothing_is_touched(tmp_path, capfd):
    root = tmp_path / "project"
    decoys = _decoys(root)
    outside, kept = _outside(tmp_path)
    (root / "link").symlink_to(outside, target_is_directory=True)
    (root / "cd").symlink_to(outside, target_is_directory=True)  # named like a shard
    _age(root)
    before = sorted(p.relative_to(root) for p in root.rglob("*"))
    out = tmp_path / "out"
    rc = main(["reference", "plate", *SMALL, "--cache-dir", str(root), "--out", str(out)])
    err = capfd.readouterr().err.strip().splitlines()
    assert rc == 0 and (out / "reference.exr").is_file()
    assert len(err) == 1 and "holds files that are not the cache's" in err[0], err
    assert json.loads((out / "reference.json").read_text())["cache_status"] == "skipped"
    _survive(decoys)
    _survive(kept)
    assert sorted(p.relative_to(root) for p in root.rglob("*")) == before  # nothing added


def test_housekeeping_in_a_marked_cache_never_follows_links(tmp_path):
    root = tmp_path / "cache"
    cache = cache_mod.ReferenceCache(root)
    assert cache.usable() is None and (root / cache_mod.MARKER).is_file()
    outside, kept = _outside(tmp_path)
    shard = root / "ab"
    shard.mkdir()
    (shard / ".0123abcd.1@host.x").symlink_to(outside, target_is_directory=True)
    (shard / ".0123abcd.2@host.y").mkdir()
    (shard / ".0123abcd.2@host.y" / "foreign.txt").write_bytes(b"not the cache's\n")
    (root / "cd").symlink_to(outside, target_is_directory=True)  # a link as a shard
    (root / "notes").mkdir()
    (root / "notes" / ".draft.md").write_bytes(b"draft\n")
    _age(root)
    src = tmp_path / "src"
    src.mkdir()
    (src / "reference.exr").write_bytes(b"exr")
    (src / "reference.json").write_text("{}")
    for key in ("ab" + "1" * 62, "cd" + "2" * 62):
        entry = cache.store(key, src)
        assert entry is not None and cache.lookup(key) == (entry, "hit")
    _survive(kept)
    assert (shard / ".0123abcd.1@host.x").is_symlink()
    assert (shard / ".0123abcd.2@host.y" / "foreign.txt").read_bytes() == b"not the cache's\n"
    assert (root / "notes" / ".draft.md").read_bytes() == b"draft\n"
    assert (root / "cd").is_dir() and not (root / "cd").is_symlink()


def _reseal(entry):
    """Rewrite checksums.json so that the entry's checksums match its (damaged) files."""
    sums = {n: hashlib.sha256((entry / n).read_bytes()).hexdigest() for n in cache_mod.FILES}
    (entry / "checksums.json").write_text(json.dumps(sums))


def _damage_record(text):
    def damage(entry):
        (entry / "reference.json").write_text(text)

    return damage


def _damage_image(entry):
    write_exr(entry / "reference.exr", {"visibility": np.ones((8, 8), np.float32)})


def test_damaged_entries_with_consistent_checksums_are_rendered_again(tmp_path, capfd):
    root = tmp_path / "cache"
    args = ["reference", "plate", *SMALL, "--cache-dir", str(root)]
    assert main([*args, "--out", str(tmp_path / "first")]) == 0
    first = (tmp_path / "first" / "reference.exr").read_bytes()
    entry = next(root.glob("*/" + "[0-9a-f]" * 64))
    damages = {
        "not JSON": _damage_record("{not json"),
        "a JSON list": _damage_record("[1, 2]"),
        "another key": _damage_record(json.dumps({"cache_key": "0" * 64})),
        "8x8 image": _damage_image,
    }
    for i, damage in enumerate(damages.values()):
        damage(entry)
        _reseal(entry)
        out = tmp_path / f"o{i}"
        assert main([*args, "--out", str(out)]) == 0
        record = json.loads((out / "reference.json").read_text())
        assert record["cache_status"] == "corrupted" and record["resolution"] == [16, 12]
        assert (out / "reference.exr").read_bytes() == first
    capfd.readouterr()
    assert main([*args, "--out", str(tmp_path / "last")]) == 0
    assert json.loads((tmp_path / "last" / "reference.json").read_text())["cache_status"] == "hit"


def test_an_entry_holding_foreign_files_is_left_and_not_cached(tmp_path, capfd):
    root = tmp_path / "cache"
    args = ["reference", "plate", *SMALL, "--cache-dir", str(root)]
    assert main([*args, "--out", str(tmp_path / "a")]) == 0
    entry = next(root.glob("*/" + "[0-9a-f]" * 64))
    (entry / "reference.json").write_text("damaged")
    (entry / "mine.txt").write_bytes(b"keep me\n")
    capfd.readouterr()
    assert main([*args, "--out", str(tmp_path / "b")]) == 0
    err = capfd.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cannot be read or replaced" in err[0], err
    assert (entry / "mine.txt").read_bytes() == b"keep me\n"
    assert json.loads((tmp_path / "b" / "reference.json").read_text())["cache_status"] == "skipped"
    same = (tmp_path / "a" / "reference.exr").read_bytes()
    assert (tmp_path / "b" / "reference.exr").read_bytes() == same


def test_a_cache_that_cannot_be_made_is_skipped_with_one_line(tmp_path, capfd):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    root = os.path.join("/proc", "raster-oracle-cache")  # mkdir fails, even for root
    out = tmp_path / "out"
    rc = main(["reference", "plate", *SMALL, "--cache-dir", root, "--out", str(out)])
    err = capfd.readouterr().err.strip().splitlines()
    assert rc == 0 and (out / "reference.exr").is_file()
    assert len(err) == 1 and "cannot be used" in err[0], err
    # a name no file can have is refused before any work (the one path rule)
    root = str(tmp_path / ("n" * 300))
    rc = main(["reference", "plate", *SMALL, "--cache-dir", root, "--out", str(out)])
    err = capfd.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "over the 255" in err[0], err


def test_a_cache_folder_holding_self_check_verdicts_is_claimed(tmp_path, capfd):
    """The self-check writes its verdicts into the cache folder before the first reference:
    that folder is the cache's own (claimed, used), not foreign."""
    root = tmp_path / "cache"
    (root / "self-check").mkdir(parents=True)
    (root / "self-check" / "llvm_ad_rgb-0123.json").write_text("{}")
    args = ["reference", "plate", *SMALL, "--cache-dir", str(root)]
    assert main([*args, "--out", str(tmp_path / "a")]) == 0
    assert main([*args, "--out", str(tmp_path / "b")]) == 0
    assert "warning" not in capfd.readouterr().err
    assert (root / cache_mod.MARKER).is_file()
    assert json.loads((tmp_path / "b" / "reference.json").read_text())["cache_status"] == "hit"
