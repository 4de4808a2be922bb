"""What ``score`` reads: the candidate's layout (printed), its size against the scene's, and
the export folder a candidate was rendered from.

Kept apart from the option block of :mod:`oracle.cli.score` so that both stay short.
"""

from __future__ import annotations

from pathlib import Path

from . import args as A

__all__ = ["candidate_inputs", "candidate_size", "resolve_layout"]


def candidate_size(path: str | Path) -> tuple[int, int] | None:
    """``(width, height)`` of a candidate EXR or PNG (None when it cannot be read: the read
    itself then reports the problem)."""
    from ..scoring.layout import candidate_format

    path = Path(path)
    try:
        return candidate_format(path).size(path)
    except Exception:  # unreadable: the candidate reader says why, in one line
        return None


def _check_size(path: str, loaded) -> None:
    size = candidate_size(path)
    if size is None or size == (loaded.width, loaded.height):
        return
    w, h = size
    from ...scenes.formats.inputs import nearest_export

    found = nearest_export(Path(path), size)
    export = (
        f"score the export folder {found} that wrote it"
        if found
        else ("score the export folder that wrote it (`score EXPORT_DIR`)")
    )
    raise A.CliError(
        f"candidate is {w}x{h}, the reference is {loaded.width}x{loaded.height} "
        f"({Path(path).name}): pass --width {w} --height {h}, or {export}"
    )


def resolve_layout(pattern: str, *, channel: str | None, kind: str | None, loaded):
    """The layout of a candidate file or ``{frame}`` pattern (frame 0's file) with
    ``channel`` / ``kind``, printed as one line, after checking its size against
    ``loaded``'s."""
    from ..scoring.layout import candidate_layout
    from ..scoring.request import frame_file

    first = frame_file(pattern, 0)
    layout = candidate_layout(first, channel=channel, kind=kind)
    _check_size(first, loaded)
    print(layout.message(Path(first).name), flush=True)
    return layout


def candidate_inputs(args, loaded):
    """:func:`resolve_layout` of ``--candidate`` with ``--channel`` / ``--kind``; None for a
    technique."""
    if args.candidate is None:
        if args.kind is not None:
            raise A.CliError("--kind applies to --candidate files, not to --technique")
        return None
    return resolve_layout(args.candidate, channel=args.channel, kind=args.kind, loaded=loaded)
