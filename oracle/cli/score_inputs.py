"""What ``score`` reads: the candidate's layout (printed), its size against the scene's, and
the export folder a candidate was rendered from.

Kept apart from the option block of :mod:`oracle.cli.score` so that both stay short.
"""

from __future__ import annotations

from . import args as A

__all__ = ["candidate_inputs", "resolve_layout"]


def resolve_layout(pattern: str, *, channel: str | None, kind: str | None, loaded):
    """The layout of a candidate file or ``{frame}`` pattern (frame 0's file) with
    ``channel`` / ``kind``, printed as one line, after checking its size against
    ``loaded``'s (the library's :func:`oracle.scoring.folder_cases.resolve_layout`)."""
    from ..scoring.folder_cases import resolve_layout as resolve

    return resolve(pattern, channel=channel, kind=kind, loaded=loaded)


def candidate_inputs(args, loaded):
    """:func:`resolve_layout` of ``--candidate`` with ``--channel`` / ``--kind``; None for a
    technique."""
    if args.candidate is None:
        if args.kind is not None:
            raise A.CliError("--kind applies to --candidate files, not to --technique")
        return None
    return resolve_layout(args.candidate, channel=args.channel, kind=args.kind, loaded=loaded)
