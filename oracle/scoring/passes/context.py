"""What the passes of one score share: the request, the scored frames and what each pass adds
to the record (built once, last, by :func:`oracle.scoring.result.build_record`)."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

from ...phases import Phases
from ..result import ScoreResult

__all__ = ["NOTE_ORDER", "ScoreContext"]

#: The passes whose notes the verdict shows, in this order.
NOTE_ORDER = ("conformance", "diagnosis", "receivers")


@dataclass
class ScoreContext:
    """The state of one score while its passes run.

    ``result``: the frames scored (metrics, maps, references, candidates); ``references``:
    each frame's reference (its folder, metadata and channels); ``kw``: frame 0's keywords
    of :func:`oracle.scoring.channels.metrics_for` (the noise floor's); ``summary``: the
    record's metric values (per-frame means, then what the passes add); ``sections``: the
    record's sections after the reference, by name, as the passes add them; ``phases``:
    wall seconds by pass (the frames first).
    """

    request: object
    result: ScoreResult = field(default_factory=lambda: ScoreResult(record={}))
    references: list = field(default_factory=list)
    #: each frame's reference standard error of the scored channel (the engine gates')
    stderrs: list = field(default_factory=list)
    kw: dict | None = None
    exposure: float | None = None
    flip_range: tuple | None = None
    infos: list = field(default_factory=list)
    engine_motion: list = field(default_factory=list)
    coverage_truth: dict | None = None
    exact_frames: object = None
    summary: dict = field(default_factory=dict)
    sections: dict = field(default_factory=dict)
    phases: Phases = field(default_factory=Phases)
    started: float = field(default_factory=time.perf_counter)
    #: the notes of the verdict, by pass (:data:`NOTE_ORDER`)
    notes: dict = field(default_factory=dict)
    #: how a pass scores another request (``score`` itself: the coverage pass's channel)
    rescore: object = None

    @property
    def scenes(self) -> list:
        return self.request.frame_scenes

    def note_lines(self) -> list[str]:
        """The passes' notes, in :data:`NOTE_ORDER`."""
        return [line for name in NOTE_ORDER for line in self.notes.get(name, ())]

    @property
    def floor(self) -> dict | None:
        """Frame 0's noise floor: the record's ``noise_floor``."""
        return self.result.frames[0].noise_floor if self.result.frames else None
