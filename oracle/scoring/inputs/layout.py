"""Which image of an engine's file is scored, and as what: the candidate's *layout*.

An engine writes one EXR with several layers (``color.R/G/B``, ``shadow.Y``,
``msaa.coverage``) or a PNG. :func:`candidate_layout` decides, once per file, what is read and
what *kind* of image it is (``visibility``, ``color``, ``coverage`` or ``depth``: the kind
picks the reference channels and the metrics), and says so in one line for the log
(``candidate shadow.exr: visibility from channel 'shadow.Y'``).

Inference is done only when the answer is unambiguous, because a wrong guess scores a shadow
mask as colour and every shadow metric silently becomes null:

- an EXR holding a single image: one grey channel (``Y``, ``visibility``, ``shadow.Y``, any
  lone channel) is ``visibility`` (``coverage`` when its name says coverage, ``depth`` when
  its name or layer is ``depth`` or ``view_depth``); one R/G/B group
  (top level or one layer) is ``color``;
- a grey (or grey + alpha, 8 or 16 bit) PNG is ``visibility``; an RGB(A) or palette PNG is
  ``color``;
- anything else (an EXR with several layers, RGB plus a coverage channel, RGB plus depth) is
  an error that names the ``--channel`` values to choose from.

``channel`` addresses what engines write: a kind (``visibility``, ``color``, ``coverage``,
``depth``: the kind's usual channel names are looked up; depth: :data:`DEPTH_CHANNELS`), an
exact channel (``msaa.coverage``, ``shadow.Y``) or a layer (``shadow``: its one channel, or
its R/G/B group as colour). Alpha (``A``, ``<layer>.A``) is never an image. A miss lists
the file's channels and layers.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...reference.exr import ExrError, read_exr
from .candidates import (
    CandidateError,
    MissingChannelError,
    check_candidate_values,
    png_is_grey,
    read_png,
)

__all__ = [
    "FORMATS",
    "KINDS",
    "CandidateFormat",
    "CandidateLayout",
    "candidate_format",
    "candidate_layout",
    "load_candidate",
    "read_candidate",
]

#: What a candidate image can be: it picks the reference channels and the metrics.
KINDS = ("visibility", "color", "coverage", "depth")
_RGB = ("R", "G", "B")


@dataclass(frozen=True)
class CandidateLayout:
    """What is read from a candidate file and what kind of image it is.

    ``names``: the EXR channels read (one grey channel; three ``R, G, B`` channels; for a
    colour candidate one ``Y`` channel, replicated); empty for a PNG, which is read whole.
    ``source``: how the log names them (``channel 'shadow.Y'``, ``grey PNG values``).
    """

    kind: str
    names: tuple[str, ...]
    source: str

    def message(self, file_name: str) -> str:
        """One log line: ``candidate shadow.exr: visibility from channel 'shadow.Y'``."""
        return f"candidate {file_name}: {self.kind} from {self.source}"


def _leaf(name: str) -> str:
    return name.rsplit(".", 1)[-1]


def _layer(name: str) -> str:
    return name.rsplit(".", 1)[0] if "." in name else ""


def _is_alpha(name: str) -> bool:
    return _leaf(name) == "A"


def _inventory(names) -> tuple[list[str], list[str]]:
    """(R/G/B group prefixes ``""`` or ``"layer."``, grey channels outside those groups)."""
    data = [n for n in names if not _is_alpha(n)]
    prefixes = sorted({n[: -len(_leaf(n))] for n in data if _leaf(n) in _RGB})
    groups = [p for p in prefixes if all(p + c in names for c in _RGB)]
    in_group = {p + c for p in groups for c in _RGB}
    greys = [n for n in data if n not in in_group]
    return groups, greys


def _grey_kind(name: str, kind: str | None) -> str:
    """The kind of a grey channel: ``kind`` if given, ``coverage`` when the channel or its
    layer is named so (``coverage``, ``msaa.coverage``), else ``visibility``."""
    if kind is not None:
        return kind
    parts = name.lower().split(".")
    return "coverage" if "coverage" in parts or "msaa" in parts else "visibility"


def _choice(prefix: str) -> str:
    """The ``--channel`` value that picks an R/G/B group."""
    return prefix[:-1] if prefix else "color"


def _rgb_layout(prefix: str, kind: str | None) -> CandidateLayout:
    names = tuple(prefix + c for c in _RGB)
    return CandidateLayout(kind or "color", names, "channels " + ", ".join(names))


#: Grey channel names (or layers) that hold depth, never a mask: read as the ``depth`` kind.
DEPTH_NAMES = ("depth", "view_depth")
#: What ``--channel depth`` reads, the first present: the engines' usual depth channels.
DEPTH_CHANNELS = ("depth", "Z", "depth.Z", "depth.Y", "depth.R", "view_depth")


def _grey_layout(name: str, kind: str | None) -> CandidateLayout:
    if kind is None and any(p in DEPTH_NAMES for p in name.lower().split(".")):
        kind = "depth"
    kind = _grey_kind(name, kind)
    if kind == "color":
        return CandidateLayout("color", (name,), f"channel {name!r} (grey, replicated)")
    return CandidateLayout(kind, (name,), f"channel {name!r}")


def _listing(names) -> str:
    layers = sorted({_layer(n) for n in names if _layer(n)})
    text = f"channels: {', '.join(sorted(names))}"
    return text + (f"; layers: {', '.join(layers)}" if layers else "")


def _exr_infer(file_name: str, names, kind: str | None) -> CandidateLayout:
    groups, greys = _inventory(names)
    if len(groups) + len(greys) == 1:
        return _rgb_layout(groups[0], kind) if groups else _grey_layout(greys[0], kind)
    if not groups and not greys:
        raise CandidateError(f"candidate {file_name} holds no image channel ({_listing(names)})")
    choices = [_choice(p) for p in groups] + greys
    raise CandidateError(
        f"candidate {file_name} holds several images ({', '.join(choices)}); pick one with "
        f"--channel {' or '.join(choices)}"
    )


def _exr_kind(file_name: str, names, kind: str) -> CandidateLayout:
    """``--channel visibility|color|coverage|depth``: the kind's usual channels, in order."""
    groups, greys = _inventory(names)
    if kind == "depth":
        for name in DEPTH_CHANNELS:
            if name in names:
                return _grey_layout(name, kind)
        raise MissingChannelError(
            f"candidate {file_name} has no depth channel ({', '.join(DEPTH_CHANNELS)}); "
            f"{_listing(names)}"
        )
    if kind == "color":
        for prefix in ("color.", ""):
            if prefix in groups:
                return _rgb_layout(prefix, kind)
        if len(groups) == 1:
            return _rgb_layout(groups[0], kind)
        if len(groups) > 1:
            raise CandidateError(
                f"candidate {file_name} has several colour layers; pick one with --channel "
                + " or ".join(_choice(p) for p in groups)
            )
        if "Y" in names:
            return _grey_layout("Y", kind)
        raise MissingChannelError(
            f"candidate {file_name} has no channel 'color'; {_listing(names)}"
        )
    if kind in names:
        return _grey_layout(kind, kind)
    for found in ([n for n in greys if _leaf(n) == kind], ["Y"] if "Y" in greys else []):
        if len(found) == 1:
            return _grey_layout(found[0], kind)
    # grey channels not named for another kind (a coverage mask is not a shadow mask)
    other = set(KINDS) - {kind, "depth"}
    plain = [n for n in greys if not set(n.lower().split(".")) & other]
    if len(plain) == 1:
        return _grey_layout(plain[0], kind)
    if len(plain) > 1:
        raise CandidateError(
            f"candidate {file_name} has several grey channels for {kind}; pick one with "
            f"--channel {' or '.join(plain)}"
        )
    if "" in groups:  # grey stored as equal R, G, B: checked when read
        return _rgb_layout("", kind)
    raise MissingChannelError(f"candidate {file_name} has no channel {kind!r}; {_listing(names)}")


def _exr_named(file_name: str, names, channel: str, kind: str | None) -> CandidateLayout:
    """``--channel NAME``: an exact channel, else the layer ``NAME.*``."""
    if channel in names:
        return _grey_layout(channel, kind)
    members = [n for n in names if n.startswith(channel + ".") and not _is_alpha(n)]
    if all(f"{channel}.{c}" in members for c in _RGB):
        return _rgb_layout(channel + ".", kind)
    if len(members) == 1:
        return _grey_layout(members[0], kind)
    if members:
        raise CandidateError(
            f"candidate {file_name} layer {channel!r} holds {', '.join(sorted(members))}; "
            f"pick one with --channel {' or '.join(sorted(members))}"
        )
    raise MissingChannelError(
        f"candidate {file_name} has no channel or layer {channel!r}; {_listing(names)}"
    )


def _png_layout(path: Path, channel: str | None, kind: str | None) -> CandidateLayout:
    want = kind or channel
    if want == "depth" or (want is not None and want not in KINDS):
        raise MissingChannelError(
            f"candidate {path.name} is a PNG, which has no named channels and no depth: "
            f"--channel must be one of {', '.join(k for k in KINDS if k != 'depth')}, "
            f"got {channel!r}"
        )
    grey = png_is_grey(path)
    if want is None:
        want = "visibility" if grey else "color"
    if want == "color":
        return CandidateLayout("color", (), f"{'grey' if grey else 'colour'} PNG (sRGB-decoded)")
    return CandidateLayout(want, (), f"{'grey' if grey else 'equal R, G, B'} PNG values (data)")


def candidate_layout(
    path: str | os.PathLike, *, channel: str | None = None, kind: str | None = None
) -> CandidateLayout:
    """Decide what to read from the candidate file ``path`` and what kind it is.

    Parameters
    ----------
    channel : None (infer; only when the file holds one image), a kind (``visibility``,
        ``color``, ``coverage``), an EXR channel (``msaa.coverage``) or layer (``shadow``).
    kind : force the kind of a named channel or layer (None: from its name and contents).

    Raises
    ------
    CandidateError
        Missing or unreadable file, an ambiguous file without ``channel`` (the choices are
        named), a channel or layer that is not there (the file's are listed).
    """
    path = Path(path)
    if kind is not None and kind not in KINDS:
        raise CandidateError(f"kind must be one of {', '.join(KINDS)}, got {kind!r}")
    if channel is not None and (not isinstance(channel, str) or not channel):
        raise CandidateError(f"channel must be a non-empty string, got {channel!r}")
    if not path.is_file():
        raise CandidateError(f"candidate file not found: {path}")
    return candidate_format(path).layout(path, channel, kind)


def _exr_names(path: Path) -> list[str]:
    try:
        return sorted(read_exr(path))
    except ExrError as exc:
        raise CandidateError(
            f"candidate {path.name} is truncated or not a readable EXR ({exc})"
        ) from exc


def _exr_layout(path: Path, channel: str | None, kind: str | None) -> CandidateLayout:
    names = _exr_names(path)
    if channel is None and kind is None:
        return _exr_infer(path.name, names, None)
    if channel is None or channel in KINDS:
        return _exr_kind(path.name, names, kind or channel)
    return _exr_named(path.name, names, channel, kind)


def read_candidate(
    path: str | os.PathLike,
    layout: CandidateLayout,
    *,
    expected_shape: tuple[int, int] | None = None,
    transfer: str = "srgb",
) -> np.ndarray:
    """Read ``path`` as ``layout`` says: ``(H, W, 3)`` linear colour or ``(H, W)`` data in
    [0, 1]; the same checks as :func:`load_candidate` (size,
    finite values, range) by kind. ``transfer``: how a PNG's colour is decoded
    (:data:`oracle.scoring.inputs.candidates.TRANSFERS`; EXR colour is linear already)."""
    path = Path(path)
    image = candidate_format(path).read(path, layout, expected_shape, transfer)
    return np.ascontiguousarray(image, dtype=np.float32)


def load_candidate(
    path: str | os.PathLike,
    *,
    channel: str = "color",
    expected_shape: tuple[int, int] | None = None,
    transfer: str = "srgb",
) -> np.ndarray:
    """Read one channel (or RGB group) of an engine's image as float32, by the layout rules
    of :func:`candidate_layout` (the one set of EXR channel rules).

    Parameters
    ----------
    path : ``.exr`` or ``.png`` file (extension compared case-insensitively).
    channel : a kind, ``"color"`` (linear RGB radiance: an EXR's ``color.R/G/B``, top-level
        ``R/G/B``, its only ``<layer>.R/G/B`` group or ``Y`` replicated; a PNG's decoded
        colour) or ``"visibility"`` / ``"coverage"`` (grey data in [0, 1]: the channel of
        that name, the only ``<layer>.<kind>``, ``Y``, the file's only plain grey channel or
        equal ``R/G/B``; a PNG's grey values); any other name: an EXR channel of that exact
        name (``"Z"``, ``"beauty.G"``, returned as it is), else a layer ``<name>.*``.
    expected_shape : the reference's ``(H, W)``; a candidate of another size is an error.
    transfer : how a PNG's colour is decoded to linear
        (:data:`oracle.scoring.inputs.candidates.TRANSFERS`).

    Returns float32, ``(H, W, 3)`` for colour and RGB layers, ``(H, W)`` otherwise; finite;
    colour non-negative, visibility and coverage in [0, 1].

    Raises
    ------
    CandidateError
        With one line saying what is wrong: file missing, unknown extension, unreadable
        file, missing channel (the file's are listed), wrong size, NaN or inf values, values
        out of their kind's range.
    """
    path = Path(path)
    layout = candidate_layout(path, channel=channel)
    if candidate_format(path) is not FORMATS[".exr"]:
        return read_candidate(path, layout, expected_shape=expected_shape, transfer=transfer)
    image = _shape_planes(path, _exr_planes(path, layout), layout)
    return check_candidate_values(path, image, expected_shape=expected_shape, kind=channel)


def _png_read(path: Path, layout: CandidateLayout, expected_shape, transfer) -> np.ndarray:
    """A PNG is read whole: colour decoded by ``transfer``, grey kinds as data."""
    read = "color" if layout.kind == "color" else "visibility"
    image = read_png(path, read, transfer)
    return check_candidate_values(path, image, expected_shape=expected_shape, kind=read)


def _exr_read(path: Path, layout: CandidateLayout, expected_shape, transfer) -> np.ndarray:
    """The channels ``layout`` names, shaped and checked by kind."""
    image = _shape_planes(path, _exr_planes(path, layout), layout)
    return check_candidate_values(path, image, expected_shape=expected_shape, kind=layout.kind)


def _exr_planes(path: Path, layout: CandidateLayout) -> list[np.ndarray]:
    """The float32 channels ``layout`` names, in order."""
    try:
        chans = read_exr(path)
    except ExrError as exc:
        raise CandidateError(
            f"candidate {path.name} is truncated or not a readable EXR ({exc})"
        ) from exc
    missing = [n for n in layout.names if n not in chans]
    if missing:
        raise MissingChannelError(
            f"candidate {path.name} has no channel {missing[0]!r} (as the first frame "
            f"had); {_listing(chans)}"
        )
    return [np.asarray(chans[n], dtype=np.float32) for n in layout.names]


def _png_size(path: Path) -> tuple[int, int]:
    from PIL import Image

    with Image.open(path) as im:
        return im.size


def _exr_size(path: Path) -> tuple[int, int]:
    h, w = next(iter(read_exr(path).values())).shape[:2]
    return w, h


@dataclass(frozen=True)
class CandidateFormat:
    """One reader per candidate file format: ``layout(path, channel, kind)`` decides what is
    read (:func:`candidate_layout`), ``read(path, layout, expected_shape)`` reads and checks
    it (:func:`read_candidate`), ``size(path)`` is ``(width, height)``."""

    name: str
    layout: Callable[[Path, str | None, str | None], CandidateLayout]
    read: Callable[[Path, CandidateLayout, tuple | None], np.ndarray]
    size: Callable[[Path], tuple[int, int]]


#: Candidate file formats by suffix (lower case): the one place a new format registers.
FORMATS = {
    ".exr": CandidateFormat("OpenEXR", _exr_layout, _exr_read, _exr_size),
    ".png": CandidateFormat("PNG", _png_layout, _png_read, _png_size),
}


def candidate_format(path) -> CandidateFormat:
    """The reader of ``path``'s suffix; :class:`CandidateError` naming the known ones."""
    path = Path(path)
    found = FORMATS.get(path.suffix.lower())
    if found is None:
        raise CandidateError(
            f"unknown candidate file extension {path.suffix or '(none)'!r} for {path.name}; "
            f"expected {' or '.join(FORMATS)}"
        )
    return found


def _shape_planes(path: Path, planes: list[np.ndarray], layout: CandidateLayout) -> np.ndarray:
    if layout.kind == "color":
        return np.stack(planes * 3 if len(planes) == 1 else planes, axis=-1)
    if len(planes) == 1:
        return planes[0]
    if not (np.array_equal(planes[0], planes[1]) and np.array_equal(planes[0], planes[2])):
        raise CandidateError(
            f"candidate {path.name} has unequal R, G, B: {layout.kind} needs one grey channel "
            "(pass --channel to pick one)"
        )
    return planes[0]
