"""The reference cache: content keys of XML scenes, corrupted entries, scratch folders."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time

import pytest
from raster_oracle.oracle.cli import main
from raster_oracle.oracle.reference import cache as cache_mod

from raster_oracle import scenes

SMALL = ["--width", "8", "--height", "6", "--spp", "1", "--quiet"]

HEAD = """<scene version="3.0.0">
  {defaults}
  <sensor type="perspective">
    <transform name="to_world"><lookat origin="0,3,5" target="0,0,0" up="0,1,0"/></transform>
    <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="6"/>
    </film>
  </sensor>
  <emitter type="directional"><vector name="direction" value="0,-1,-0.2"/></emitter>
  {body}
</scene>
"""

#: How the mesh is referenced: the forms a regex over ``name="filename" value="..."`` missed.
REFERENCES = {
    "single quotes, value first": (
        "",
        "<shape type='ply'><string value='mesh.ply' name='filename'/></shape>",
    ),
    "$param default": (
        '<default name="meshfile" value="mesh.ply"/>',
        '<shape type="ply"><string name="filename" value="$meshfile"/></shape>',
    ),
    "include": ("", "<include filename='inc.xml'/>"),
    "spaces around =": (
        "",
        '<shape type="ply"><string name = "filename" value = "mesh.ply" /></shape>',
    ),
}


def _mesh(y: float) -> str:
    """An ASCII PLY quad (two triangles) at height ``y``."""
    return (
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
        "property float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n"
        f"-1 {y} -1\n1 {y} -1\n1 {y} 1\n-1 {y} 1\n3 0 1 2\n3 0 2 3\n"
    )


def _scene(folder, form):
    defaults, body = REFERENCES[form]
    (folder / "mesh.ply").write_text(_mesh(0.0))
    (folder / "inc.xml").write_text(
        '<scene version="3.0.0"><shape type="ply">'
        '<string name="filename" value="mesh.ply"/></shape></scene>'
    )
    path = folder / "scene.xml"
    path.write_text(HEAD.format(defaults=defaults, body=body))
    return path


@pytest.mark.parametrize("form", list(REFERENCES))
def test_edited_mesh_changes_the_content_hash(tmp_path, form):
    path = _scene(tmp_path, form)
    before = scenes.load(path).content_hash
    assert scenes.load(path).content_hash == before  # same files, same key
    (tmp_path / "mesh.ply").write_text(_mesh(0.25))
    assert scenes.load(path).content_hash != before


def test_edited_mesh_misses_the_cache(tmp_path, capsys):
    path = _scene(tmp_path, "single quotes, value first")
    args = ["reference", str(path), *SMALL, "--cache-dir", str(tmp_path / "c")]
    assert main([*args, "--out", str(tmp_path / "a")]) == 0
    assert main([*args, "--out", str(tmp_path / "b")]) == 0
    (tmp_path / "mesh.ply").write_text(_mesh(0.25))
    assert main([*args, "--out", str(tmp_path / "c2")]) == 0
    status = [
        json.loads((tmp_path / n / "reference.json").read_text())["cache_status"]
        for n in ("a", "b", "c2")
    ]
    assert status == ["miss", "hit", "miss"]


def _status(folder):
    return json.loads((folder / "reference.json").read_text())["cache_status"]


def test_entry_replaced_by_a_file_is_corrupted_and_rendered_again(tmp_path, capfd):
    args = ["reference", "plate", *SMALL, "--cache-dir", str(tmp_path / "c")]
    assert main([*args, "--out", str(tmp_path / "a")]) == 0
    entry = next((tmp_path / "c").glob("*/*"))
    shutil.rmtree(entry)
    entry.write_text("not an entry")
    capfd.readouterr()
    assert main([*args, "--out", str(tmp_path / "b")]) == 0
    out, err = capfd.readouterr()
    assert "(corrupted)" in out
    assert err.strip() == "raster-oracle: warning: corrupted cache entry replaced"
    assert _status(tmp_path / "b") == "corrupted"
    exr = "reference.exr"
    assert (tmp_path / "b" / exr).read_bytes() == (tmp_path / "a" / exr).read_bytes()
    assert main([*args, "--out", str(tmp_path / "c2")]) == 0
    assert _status(tmp_path / "c2") == "hit"
    # its shard folder replaced by a file: a miss, and the store replaces the file
    shutil.rmtree(entry.parent)
    entry.parent.write_text("not a folder")
    assert main([*args, "--out", str(tmp_path / "d")]) == 0
    assert main([*args, "--out", str(tmp_path / "e")]) == 0
    assert [_status(tmp_path / n) for n in "de"] == ["miss", "hit"]


@pytest.mark.parametrize("name", cache_mod.CACHE_ENV)
def test_both_cache_variables_are_accepted(monkeypatch, tmp_path, name):
    for other in cache_mod.CACHE_ENV:
        monkeypatch.delenv(other, raising=False)
    monkeypatch.setenv(name, str(tmp_path / name))
    assert cache_mod.default_cache_dir() == tmp_path / name
    assert cache_mod.ReferenceCache().root == tmp_path / name


def test_no_cache_and_failed_runs_leave_no_scratch_folder(tmp_path, monkeypatch):
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))
    assert main(["reference", "plate", *SMALL, "--no-cache", "--out", str(tmp_path / "a")]) == 0
    assert (tmp_path / "a" / "reference.exr").is_file()
    assert list(scratch.iterdir()) == []

    from raster_oracle.oracle.reference import store as pipeline
    from raster_oracle.oracle.reference.exr import ExrError

    def broken(*a, **k):
        raise ExrError("disk full (simulated)")

    monkeypatch.setattr(pipeline, "write_exr", broken)
    for extra in (["--no-cache"], ["--cache-dir", str(tmp_path / "c")]):
        assert main(["reference", "plate", *SMALL, *extra, "--out", str(tmp_path / "b")]) == 2
        assert list(scratch.iterdir()) == []
    assert not (tmp_path / "b").exists()


def test_sweep_removes_only_old_scratch_of_dead_processes(tmp_path):
    dead = 2**22 + 12345  # above the default pid_max: no such process
    old = time.time() - 2 * cache_mod.STALE_SECONDS
    folders = {
        "dead_old": f"{cache_mod.SCRATCH_PREFIX}{dead}-a",
        "dead_new": f"{cache_mod.SCRATCH_PREFIX}{dead}-b",
        "alive_old": f"{cache_mod.SCRATCH_PREFIX}{os.getpid()}-c",
        "other": "something-else",
    }
    for key, name in folders.items():
        (tmp_path / name).mkdir()
        (tmp_path / name / "reference.exr").write_bytes(b"x")
        if key != "dead_new":
            os.utime(tmp_path / name, (old, old))
    assert cache_mod.sweep_stale_scratch(tmp=tmp_path) == 1
    left = sorted(p.name for p in tmp_path.iterdir())
    assert left == sorted(v for k, v in folders.items() if k != "dead_old")


def test_sigterm_during_a_render_leaves_no_scratch_folder(tmp_path):
    """A terminated run unwinds (SIGTERM -> SystemExit) and deletes its scratch folder."""
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    env = dict(os.environ, TMPDIR=str(scratch))
    argv = ["reference", "plate", "--no-cache", "--spp", "65536", "--width", "64"]
    argv += ["--height", "64", "--quiet", "--out", str(tmp_path / "o")]
    proc = subprocess.Popen([sys.executable, "-m", "raster_oracle.oracle.cli", *argv], env=env)
    try:
        deadline = time.monotonic() + 120
        while not list(scratch.iterdir()) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert list(scratch.iterdir()), "the render never started"
        proc.send_signal(signal.SIGTERM)
        rc = proc.wait(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert rc == 128 + signal.SIGTERM
    assert list(scratch.iterdir()) == []
    assert not (tmp_path / "o").exists()


def _source(folder, text="a"):
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "reference.exr").write_bytes(b"exr " + text.encode())
    (folder / "reference.json").write_text(json.dumps({"text": text}))
    return folder


def test_store_keeps_a_valid_entry_a_reader_may_hold(tmp_path):
    """Storing a key that is already cached keeps the entry (same folder, same inode, same
    files): a reader copying from it is never left with a removed folder (issue 20)."""
    cache = cache_mod.ReferenceCache(tmp_path / "cache")
    key = "ab" + "0" * 62
    first = cache.store(key, _source(tmp_path / "one"))
    inode = first.stat().st_ino
    held = open(first / "reference.exr", "rb")  # a reader in the middle of its copy
    try:
        again = cache.store(key, _source(tmp_path / "two", "b"))
        assert again == first and first.stat().st_ino == inode
        assert held.read() == b"exr a"
    finally:
        held.close()
    assert (first / "reference.exr").read_bytes() == b"exr a"
    assert cache.lookup(key) == (first, "hit")
    assert [p.name for p in first.parent.iterdir()] == [key]  # no temporary folder left


def test_store_replaces_a_corrupted_entry(tmp_path):
    cache = cache_mod.ReferenceCache(tmp_path / "cache")
    key = "cd" + "1" * 62
    entry = cache.store(key, _source(tmp_path / "one"))
    (entry / "reference.exr").write_bytes(b"bit rot")
    assert cache.store(key, _source(tmp_path / "two", "b")) == entry
    assert (entry / "reference.exr").read_bytes() == b"exr b"
    assert cache.lookup(key) == (entry, "hit")


def test_store_sweeps_temporary_folders_of_killed_writers(tmp_path):
    """A writer killed while storing leaves ``<shard>/.<key[:8]>.*``: the next store (of any
    key) removes it once it is older than STALE_TEMP_SECONDS, and keeps a fresh one."""
    cache = cache_mod.ReferenceCache(tmp_path / "cache")
    key = "ef" + "2" * 62
    shard = cache.entry("01" + "3" * 62).parent  # another shard than the key stored
    shard.mkdir(parents=True)
    stale, fresh = shard / ".ef222222.dead", shard / ".ef222222.live"
    for folder in (stale, fresh):
        _source(folder)
    old = time.time() - cache_mod.STALE_TEMP_SECONDS - 60
    os.utime(stale, (old, old))
    cache.store(key, _source(tmp_path / "src"))
    assert not stale.exists() and fresh.is_dir()


def _dead_pid() -> int:
    """The pid of a process that has ended (and been reaped)."""
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid


def test_store_removes_a_dead_writers_temporary_folder_at_once(tmp_path):
    """Issue 31: a temporary folder named after a writer of this host that no longer runs
    goes with the next store however fresh it is; a live writer's stays (this process's,
    and the parent's), and so does a fresh one of another host (its pid says nothing here)."""
    cache = cache_mod.ReferenceCache(tmp_path / "cache")
    key = "01" + "3" * 62
    shard = cache.entry(key).parent
    shard.mkdir(parents=True)
    dead = shard / (cache_mod.temp_prefix(key, pid=_dead_pid()) + "x1")
    mine = shard / (cache_mod.temp_prefix(key) + "x2")
    parent = shard / (cache_mod.temp_prefix(key, pid=os.getppid()) + "x3")
    other_host = shard / (cache_mod.temp_prefix(key, pid=_dead_pid(), host="elsewhere") + "x4")
    for folder in (dead, mine, parent, other_host):
        _source(folder)
    cache.store("ef" + "2" * 62, _source(tmp_path / "src"))
    assert not dead.exists()
    assert mine.is_dir() and parent.is_dir() and other_host.is_dir()


#: A writer that stops in the middle of storing (after its first file) and says so.
_STALLED_WRITER = """
import shutil, sys, time
from raster_oracle.oracle.reference import cache as cache_mod
copy = shutil.copyfile
def stall(src, dst, **kw):
    copy(src, dst, **kw)
    print("stalled", flush=True)
    time.sleep(600)
shutil.copyfile = stall
cache_mod.ReferenceCache(sys.argv[1]).store(sys.argv[2], __import__("pathlib").Path(sys.argv[3]))
"""


def test_writer_killed_while_storing_leaves_nothing_after_the_next_store(tmp_path):
    """Issue 31: ``kill -9`` of a writer in the middle of storing a reference leaves its
    temporary folder; the next writer (another key) removes it, and the killed key is
    stored again whole."""
    root = tmp_path / "cache"
    key = "ab" + "4" * 62
    src = _source(tmp_path / "src")
    writer = subprocess.Popen(
        [sys.executable, "-c", _STALLED_WRITER, str(root), key, str(src)],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert writer.stdout.readline().strip() == "stalled"
        left = list(root.glob("*/.*"))
        assert len(left) == 1 and (left[0] / "reference.exr").is_file()
        assert left[0].name.startswith(cache_mod.temp_prefix(key, pid=writer.pid))
    finally:
        writer.send_signal(signal.SIGKILL)
        writer.wait()
        writer.stdout.close()
    cache = cache_mod.ReferenceCache(root)
    assert cache.lookup(key) == (None, "miss")
    cache.store("cd" + "5" * 62, _source(tmp_path / "other", "b"))
    assert list(root.glob("*/.*")) == []
    entry = cache.store(key, src)
    assert cache.lookup(key) == (entry, "hit")
