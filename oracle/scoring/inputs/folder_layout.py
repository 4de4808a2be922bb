"""A folder of engine images laid out by scene and frame (``raster-oracle score-folder``).

``ROOT/<scene>.exr`` (or ``.png``) is one frame of ``<scene>``; ``ROOT/<scene>/frame_000.exr``,
``frame_001.exr``, ... are the frames of a camera path (numbered from 0 without gaps, one
extension and one digit count). ``<scene>`` is a built-in scene or, with ``exports``, a
folder ``exports/<scene>`` written by ``export``. Names starting with ``.`` and files of
other types are ignored, so notes and logs may sit beside the images.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from ..result import ScoreError

__all__ = ["FolderEntry", "discover"]

_IMAGE = (".exr", ".png")
_FRAME = re.compile(r"^frame_(\d+)\.(exr|png)$", re.IGNORECASE)


@dataclass(frozen=True)
class FolderEntry:
    """One scene of a folder: its name, the candidate file or ``{frame}`` pattern, and the
    frame count (None: one frame, the scene's own camera)."""

    name: str
    pattern: str
    frames: int | None


def _frames_entry(folder: Path) -> FolderEntry:
    found = {}
    for f in folder.iterdir():
        m = _FRAME.match(f.name)
        if m and f.is_file():
            found[int(m.group(1))] = (len(m.group(1)), m.group(2), f)
    if not found:
        raise ScoreError(f"{folder} holds no frame_NNN.exr or frame_NNN.png")
    n = len(found)
    if sorted(found) != list(range(n)):
        missing = sorted(set(range(max(found) + 1)) - set(found))
        raise ScoreError(f"{folder}: frames must be numbered 0..{n - 1}; missing {missing[:5]}")
    styles = {(d, e.lower()) for d, e, _ in found.values()}
    if len(styles) != 1:
        raise ScoreError(f"{folder}: frame files mix digit counts or extensions")
    digits, ext = styles.pop()
    if n == 1:
        return FolderEntry(folder.name, str(found[0][2]), None)
    return FolderEntry(folder.name, str(folder / f"frame_{{frame:0{digits}d}}.{ext}"), n)


def discover(root: str | Path) -> list[FolderEntry]:
    """The scenes of ``root``, sorted by name.

    Raises
    ------
    ScoreError
        ``root`` is not a folder, holds no image, names a scene twice (``a.exr`` and ``a/``)
        or has a frame folder with gaps.
    """
    root = Path(root)
    if not root.is_dir():
        raise ScoreError(f"score-folder: {root} is not a folder")
    entries: dict[str, FolderEntry] = {}
    for item in sorted(root.iterdir()):
        if item.name.startswith("."):
            continue
        if item.is_dir():
            entry = _frames_entry(item)
        elif item.is_file() and item.suffix.lower() in _IMAGE:
            entry = FolderEntry(item.stem, str(item), None)
        else:
            continue
        if entry.name in entries:
            raise ScoreError(f"score-folder: scene {entry.name!r} is given twice in {root}")
        entries[entry.name] = entry
    if not entries:
        raise ScoreError(f"score-folder: {root} holds no <scene>.exr/.png or <scene>/frame_000.exr")
    return list(entries.values())
