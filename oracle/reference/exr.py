"""Float32 EXR files with named channels, written atomically.

Channels are a flat mapping ``name -> (H, W) array``; dotted names (``color.R``) are kept as
they are, so the file lists exactly the channels given. Reading returns the same flat
mapping. Writes go to a temporary name in the target folder and are renamed into place, so a
reader never sees a half-written file.
"""

from __future__ import annotations

import contextlib
import io
import os
import sys
import tempfile
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ...scenes.base.files import atomic_write
from ..errors import InputError

__all__ = ["ExrError", "read_exr", "write_exr"]


class ExrError(InputError):
    """An EXR file that cannot be read or channels that cannot be written."""


def write_exr(
    path: str | os.PathLike,
    channels: Mapping[str, np.ndarray],
) -> None:
    """Write float32 channels, each ``(H, W)``, to a ZIP-compressed scanline EXR atomically.

    ``uint32`` arrays are written as UINT channels; every other dtype is cast to float32.
    """
    import OpenEXR

    if not channels:
        raise ExrError("no channels to write")
    shapes = {name: np.shape(a) for name, a in channels.items()}
    first = next(iter(shapes.values()))
    if len(first) != 2 or any(s != first for s in shapes.values()):
        raise ExrError(f"channels must all be 2-D arrays of one shape, got {shapes}")
    data = {}
    for name, arr in channels.items():
        arr = np.asarray(arr)
        arr = arr.astype(np.uint32 if arr.dtype == np.uint32 else np.float32, copy=False)
        data[name] = np.ascontiguousarray(arr)
    hdr = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}

    def write(tmp: str) -> None:
        with OpenEXR.File(hdr, data) as f:
            if _is_utf8(tmp):
                f.write(tmp)
            else:  # OpenEXR takes file names as UTF-8 text only (issue 48)
                buffer = io.BytesIO()
                f.write(buffer)
                Path(tmp).write_bytes(buffer.getvalue())

    atomic_write(path, write)


@contextlib.contextmanager
def _silenced_stdio():
    """Send file descriptors 1 and 2 to /dev/null: the OpenEXR C/C++ library prints its own
    messages about a corrupt file (on stdout and stderr) before raising, and the exception
    already says what went wrong."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = []
    try:
        for fd in (1, 2):
            try:
                saved.append((fd, os.dup(fd)))
            except OSError:  # that stream is closed
                continue
        with open(os.devnull, "wb") as null:
            for fd, _ in saved:
                os.dup2(null.fileno(), fd)
        with contextlib.redirect_stderr(io.StringIO()), contextlib.redirect_stdout(io.StringIO()):
            yield
    finally:
        for fd, copy in saved:
            os.dup2(copy, fd)
            os.close(copy)


def _is_utf8(path) -> bool:
    try:
        os.fsencode(path).decode("utf-8")
    except UnicodeDecodeError:
        return False
    return True


@contextlib.contextmanager
def _utf8_name(path: Path):
    """A name OpenEXR can open for ``path``: its own when it is UTF-8, else a link with a
    plain name in a fresh temporary folder (OpenEXR takes file names as UTF-8 text: a file
    whose name is other bytes was refused as truncated, issue 48)."""
    if _is_utf8(path):
        yield str(path)
        return
    with tempfile.TemporaryDirectory(prefix="raster-oracle-exr-") as tmp:
        link = os.path.join(tmp, "image.exr")
        os.symlink(os.path.abspath(path), link)
        yield link


def read_exr(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Read every channel of an EXR as a flat ``name -> (H, W)`` mapping.

    Raises
    ------
    ExrError
        When the file is missing, truncated or not an EXR.
    """
    import OpenEXR

    path = Path(path)
    if not path.is_file():
        raise ExrError(f"EXR file not found: {path}")
    try:
        with (
            _utf8_name(path) as name,
            _silenced_stdio(),
            OpenEXR.File(name, separate_channels=True) as f,
        ):
            out = {name: np.array(ch.pixels) for name, ch in f.channels().items()}
    except Exception as exc:  # OpenEXR raises plain Exceptions for corrupt files
        raise ExrError(f"cannot read EXR {path}: {exc}") from exc
    if not out:
        raise ExrError(f"EXR {path} has no channels")
    return out
