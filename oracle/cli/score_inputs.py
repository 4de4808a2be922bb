"""What ``score`` reads: the candidate's layout (printed) and its size against the scene's.

Kept apart from the option block of :mod:`oracle.cli.score` so that both stay short.
"""

from __future__ import annotations

from . import args as A

__all__ = ["candidate_inputs"]


def candidate_inputs(args, loaded):
    """The layout of ``--candidate`` with ``--channel`` / ``--kind``, resolved once by the
    library (:func:`oracle.scoring.inputs.folder_cases.resolve_layout`: printed, its size checked
    against the scene's); None for a technique."""
    from ..scoring.inputs.folder_cases import resolve_layout

    if args.candidate is None:
        if args.kind is not None:
            raise A.CliError("--kind applies to --candidate files, not to --technique")
        return None
    return resolve_layout(args.candidate, channel=args.channel, kind=args.kind, loaded=loaded)
