"""libLLVM discovery and variant selection, with fake library folders."""

from __future__ import annotations

import pytest
from raster_oracle.scenes import backend


def _touch(folder, *names):
    folder.mkdir(parents=True, exist_ok=True)
    for n in names:
        (folder / n).write_bytes(b"")


@pytest.mark.parametrize(
    ("name", "version"),
    [
        ("libLLVM-19.so", 19),
        ("libLLVM.so.19.1", 19),
        ("libLLVM-15.so.1", 15),
        ("libLLVM-14.0.6.so.1", 14),
        ("libLLVM.so", None),
        ("libLLVMSupport.a", None),
        ("libfoo.so.19", None),
    ],
)
def test_llvm_version_of(name, version):
    assert backend.llvm_version_of(name) == version


def test_finds_newest_usable_version(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    _touch(a, "libLLVM-15.so", "libLLVM-15.so.1", "libLLVM-14.so")
    _touch(b, "libLLVM.so.17.0", "libLLVM-19.so", "libLLVM.so.19.1")
    found = backend.find_libllvm(search_dirs=[str(a), str(b)], env={})
    assert found == str(b / "libLLVM-19.so")


def test_only_old_versions_finds_nothing(tmp_path):
    _touch(tmp_path, "libLLVM-15.so.1", "libLLVM-14.0.6.so.1", "libLLVM.so")
    assert backend.find_libllvm(search_dirs=[str(tmp_path)], env={}) is None


def test_missing_folders_are_skipped(tmp_path):
    _touch(tmp_path / "x", "libLLVM-16.so")
    dirs = [str(tmp_path / "nope"), str(tmp_path / "x")]
    assert backend.find_libllvm(search_dirs=dirs, env={}) == str(tmp_path / "x" / "libLLVM-16.so")


def test_env_variable_wins(tmp_path):
    _touch(tmp_path, "libLLVM-19.so", "custom-llvm.so")
    env = {"DRJIT_LIBLLVM_PATH": str(tmp_path / "custom-llvm.so")}
    assert backend.find_libllvm(search_dirs=[str(tmp_path)], env=env) == env["DRJIT_LIBLLVM_PATH"]


def test_env_variable_naming_missing_file_is_ignored(tmp_path):
    _touch(tmp_path, "libLLVM-18.so")
    env = {"DRJIT_LIBLLVM_PATH": str(tmp_path / "gone.so")}
    assert backend.find_libllvm(search_dirs=[str(tmp_path)], env=env) == str(
        tmp_path / "libLLVM-18.so"
    )


def test_unknown_backend_is_a_clear_error():
    with pytest.raises(backend.BackendError, match="unknown backend 'vulkan'.*llvm_ad_rgb"):
        backend.select("vulkan")


def test_cannot_switch_variant_in_process(_backend):
    other = "scalar_rgb" if _backend.variant != "scalar_rgb" else "llvm_ad_rgb"
    with pytest.raises(backend.BackendError, match="already active"):
        backend.select(other)


def test_active_backend_is_vectorized_here(_backend):
    # The project's set-up installs libllvm19, so tests run on a vectorized variant.
    assert _backend.variant in ("llvm_ad_rgb", "cuda_ad_rgb")
    assert backend.select("auto") is _backend


def test_doctor_exits_2_with_install_hint_without_a_vectorized_backend(tmp_path):
    """In a child process whose library search finds no libLLVM >= 16 and no CUDA."""
    import subprocess
    import sys

    code = (
        "import sys; from raster_oracle.scenes import backend\n"
        "backend.DEFAULT_LIBRARY_DIRS = ()\n"
        "backend.cuda_works = lambda: False\n"
        "from raster_oracle.oracle.cli.app import main\n"
        "sys.exit(main(['--backend', 'scalar_rgb', 'doctor']))\n"
    )
    env = {k: v for k, v in __import__("os").environ.items() if k != "DRJIT_LIBLLVM_PATH"}
    res = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120
    )
    assert res.returncode == 2, res.stderr
    assert "apt-get install -y libllvm19" in res.stderr
    assert '"variant": "scalar_rgb"' in res.stdout


def test_auto_without_llvm_falls_back_to_scalar_with_warning():
    import subprocess
    import sys

    code = (
        "import warnings, sys; from raster_oracle.scenes import backend\n"
        "backend.DEFAULT_LIBRARY_DIRS = ()\n"
        "backend.cuda_works = lambda: False\n"
        "with warnings.catch_warnings(record=True) as w:\n"
        "    warnings.simplefilter('always')\n"
        "    info = backend.select('auto', env={})\n"
        "print(info.variant, any('slow scalar_rgb' in str(x.message) for x in w))\n"
    )
    env = {k: v for k, v in __import__("os").environ.items() if k != "DRJIT_LIBLLVM_PATH"}
    res = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120
    )
    assert res.stdout.split() == ["scalar_rgb", "True"], res.stderr


def test_keep_freed_memory_applies_on_glibc_and_can_be_turned_off():
    """glibc accepts both thresholds (mallopt returns 1); RASTER_ORACLE_KEEP_HEAP=0 skips."""
    import platform

    assert backend.keep_freed_memory({"RASTER_ORACLE_KEEP_HEAP": "0"}) is False
    on_glibc = platform.system() == "Linux" and platform.libc_ver()[0] == "glibc"
    assert backend.keep_freed_memory({}) is on_glibc
