"""An engine's frame files: a ``str.format`` pattern with a ``{frame}`` field names frame ``k``'s
file; :func:`file_candidate` reads and checks each frame (and its motion vectors) as its
layout says, and :func:`candidate_name` is how records name the files."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..result import ScoreError
from .candidates import load_motion
from .layout import CandidateLayout, candidate_layout, read_candidate

__all__ = ["FRAME_PATTERN", "candidate_name", "file_candidate", "frame_file"]


#: A ``{frame}`` field (with an optional format) in a candidate file pattern.
FRAME_PATTERN = re.compile(r"\{frame(?::[^}]*)?\}")


def frame_file(pattern: str, k: int) -> str:
    """The candidate file of frame ``k``: ``pattern`` formatted with ``frame=k`` when it has a
    ``{frame}`` field, else ``pattern`` itself."""
    return pattern.format(frame=k) if FRAME_PATTERN.search(pattern) else pattern


def file_candidate(
    pattern: str,
    *,
    channel: str | None,
    frames: int | None,
    layout: CandidateLayout | None = None,
    motion: dict | None = None,
    visibility: str = "1-is-lit",
    transfer: str | None = None,
):
    """Candidate callable ``(frame_scene, k) -> (image, info)`` reading (and validating) an
    engine's image of each frame: ``pattern`` formatted with ``frame=k`` when it has a
    ``{frame}`` field (required for ``frames`` > 1). Every frame is read as ``layout`` says
    (None: :func:`oracle.scoring.inputs.layout.candidate_layout` of frame 0's file and ``channel``).
    ``motion`` (``layer``, ``convention``, optional ``disocclusion``): also read each frame's
    motion vectors (:func:`oracle.scoring.inputs.candidates.load_motion`) into the info's
    ``motion`` / ``disocclusion``, which ``score`` turns into the end-point error metrics.
    A visibility mask whose 1 means shadowed (``visibility="1-is-shadowed"``) is read as
    ``1 - value``. ``transfer``: how a PNG's colour is decoded (None: sRGB).
    """
    has_frame = bool(FRAME_PATTERN.search(pattern))
    if frames and frames > 1 and not has_frame:
        raise ScoreError(
            "--frames needs a --candidate pattern with {frame}, e.g. frame_{frame:03d}.exr"
        )
    if layout is None:
        layout = candidate_layout(frame_file(pattern, 0), channel=channel)

    def run(frame_scene, k):
        path = frame_file(pattern, k)
        shape = (frame_scene.height, frame_scene.width)
        image = read_candidate(path, layout, expected_shape=shape, transfer=transfer or "srgb")
        if layout.kind == "visibility" and visibility == "1-is-shadowed":
            image = (1.0 - image).astype(np.float32)
        info = {"frame": k, "file": str(path)}
        if motion is not None:
            info["motion"], info["disocclusion"] = load_motion(path, expected_shape=shape, **motion)
        return image, info

    return run


def candidate_name(pattern: str, *, frames: int | None, camera_path: str | None) -> str:
    """How the record and the report name an engine's candidate: the file name (frame 0's
    for a one-frame pattern), or for several frames the camera path and the frame list
    (``dolly frames 0-7``), never the raw ``{frame}`` pattern."""
    n = frames or 1
    if n == 1 or not FRAME_PATTERN.search(pattern):
        return Path(frame_file(pattern, 0)).name
    return f"{camera_path or 'camera'} frames 0-{n - 1}"
