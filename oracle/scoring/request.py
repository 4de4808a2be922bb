"""A score request: what is scored, on which scene and channel, how, and with which caches.

:class:`ScoreRequest` is what :func:`oracle.scoring.score.score`,
:func:`oracle.scoring.technique.score_model`, :func:`oracle.scoring.to_folder.score_to_folder`,
a sweep's case and the Python API take or build. Its candidate is a registered technique's
model (:class:`ModelCandidate`) or an engine's image files (:class:`FileCandidate`, with their
motion vectors); :meth:`ScoreRequest.frame_scenes` is the one place that derives the scene of
each scored frame. Which score passes run is decided from it (:mod:`oracle.scoring.passes.plan`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from ... import raster_models
from .channels import CHANNEL_KIND, REFERENCE_GROUPS, scored_channel
from .inputs.frames import file_candidate, frame_file
from .inputs.layout import CandidateLayout, candidate_layout
from .options import ScoreOptions
from .result import ScoreError

__all__ = ["FileCandidate", "ModelCandidate", "ScoreRequest"]


@dataclass(frozen=True)
class ModelCandidate:
    """A registered technique run on each frame. ``runs`` (frame -> model result) is shared by
    every channel scored of one request, so the model runs once per frame."""

    technique: str
    params: dict
    runs: dict = field(default_factory=dict, compare=False, repr=False)

    def reader(self, channel: str, primary: str) -> Callable:
        """``(frame_scene, k) -> (image, info)``: the model's ``channel`` output. A model that
        writes its own velocity buffer and history rejection (``velocity_x/y``,
        ``rejected``) has them scored as an engine's motion vectors on its ``primary``
        channel (:mod:`oracle.scoring.temporal`), whatever that channel's kind."""
        technique, params, runs = self.technique, self.params, self.runs

        def run(frame_scene, k):
            if k not in runs:
                runs[k] = raster_models.run(technique, frame_scene, **params)
            res = runs[k]
            info = {
                "frame": k,
                "technique": technique,
                "cost": res.cost,
                "params": res.params,
                "diagnostics": res.diagnostics,
                "model_seconds": res.wall_seconds,
            }
            if channel == primary and "velocity_x" in res.outputs:
                info["motion"] = np.stack(
                    [res.outputs["velocity_x"], res.outputs["velocity_y"]], -1
                ).astype(np.float64)
                info["disocclusion"] = np.asarray(res.outputs["rejected"]) > 0.5
            return np.asarray(res.outputs[channel], dtype=np.float32), info

        return run


@dataclass(frozen=True)
class FileCandidate:
    """An engine's image file, or a ``{frame}`` pattern of files, read as ``layout`` says;
    ``motion``: its motion-vector layer (``layer``, ``convention``, optional
    ``disocclusion``); ``visibility``: its mask's convention; ``transfer``: how a colour
    PNG is decoded (None: an EXR's linear values, or data)."""

    pattern: str
    layout: CandidateLayout
    motion: dict | None = None
    visibility: str = "1-is-lit"
    transfer: str | None = None

    def reader(self, channel: str, primary: str, frames: int | None) -> Callable:
        return file_candidate(
            self.pattern,
            channel=channel,
            frames=frames,
            layout=self.layout,
            motion=self.motion,
            visibility=self.visibility,
            transfer=self.transfer,
        )

    def layout_record(self) -> dict:
        """The record's ``candidate_layout``: what was read, as what."""
        source = self.layout.source
        if self.transfer not in (None, "srgb"):
            source = source.replace("sRGB-decoded", f"{self.transfer}-decoded")
        return {
            "kind": self.layout.kind,
            "channels": list(self.layout.names),
            "source": source,
            "visibility": self.visibility if self.layout.kind == "visibility" else None,
            # how 8-bit colour was made linear (None: an EXR's linear values, or data)
            "transfer": self.transfer,
        }


def _transfer(pattern: str, layout: CandidateLayout, transfer: str | None) -> str | None:
    """The transfer a candidate's colour is decoded with: ``srgb`` (default) or the one
    asked for, for a colour PNG; None for an EXR (linear) or data. ``--transfer`` on a
    candidate it does not apply to is a :class:`ScoreError`."""
    png = frame_file(pattern, 0).lower().endswith(".png")
    if png and layout.kind == "color":
        return transfer or "srgb"
    if transfer is not None:
        raise ScoreError(
            f"--transfer applies to the colour of a PNG candidate; this candidate is "
            f"{layout.kind} {'PNG' if png else 'EXR'}"
        )
    return None


def _family(options: ScoreOptions, channel: str):
    """The family record an engine's files come from (``--family``; None: none); a family
    whose models do not produce the scored channel is a :class:`ScoreError`."""
    if options.family is None:
        return None
    try:
        family = raster_models.family(options.family)
    except raster_models.ModelError as exc:
        raise ScoreError(f"--family: {exc}") from None
    if channel not in family.channels:
        raise ScoreError(
            f"--family {options.family} produces {' and '.join(family.channels)}; this "
            f"candidate is {channel} (--channel names the file's channel)"
        )
    return family


@dataclass(frozen=True)
class ScoreRequest:
    """One score: ``candidate`` on ``loaded``'s ``channel``.

    loaded : the scene (frame 0 of its camera path when ``options.frames`` is given).
    channel : the scored channel (:data:`oracle.scoring.channels.REFERENCE_GROUPS`).
    candidate : a :class:`ModelCandidate`, a :class:`FileCandidate`, or any callable
        ``(frame_scene, k) -> (image, info)`` (a library caller's own frames; ``info`` may
        carry ``motion`` and ``disocclusion``).
    options : :class:`oracle.scoring.options.ScoreOptions` (spp, seed, frames, camera path,
        FLIP, gate frames, the engine conventions).
    cache, floor_cache : the reference cache, and a dict of noise floors shared between
        requests (a sweep worker's; keyed by reference and scoring options).
    family : the technique family (:class:`raster_models.Family`) of a model, or of files
        (``options.family``; None: none).
    aa_samples : samples per pixel of an anti-aliasing model (its coverage floor).
    coverage_only : a coverage channel scored beside colour: only its coverage metrics.
    """

    loaded: object
    channel: str
    candidate: object
    options: ScoreOptions = field(default_factory=ScoreOptions)
    cache: object = None
    floor_cache: dict | None = field(default=None, compare=False)
    family: object = None
    aa_samples: int | None = None
    coverage_only: bool = False

    # ------------------------------------------------------------------ building

    @classmethod
    def for_model(
        cls,
        loaded,
        technique: str,
        params: dict | None = None,
        *,
        channel: str | None = None,
        options: ScoreOptions | None = None,
        cache=None,
        floor_cache: dict | None = None,
    ) -> ScoreRequest:
        """A technique model's request: ``channel`` asked for (None: the primary one; an
        anti-aliasing model scores colour with its coverage merged whatever is asked); a
        channel the technique does not produce is a :class:`ScoreError`."""
        family = raster_models.family(technique)
        produced = family.channels
        if channel is not None and channel not in produced:
            raise ScoreError(
                f"technique {technique} produces {' and '.join(produced)}; "
                f"--channel {channel} does not apply"
            )
        primary = channel if channel is not None and family.coverage_channel is None else None
        return cls(
            loaded,
            primary or produced[0],
            ModelCandidate(technique, dict(params or {})),
            options=options or ScoreOptions(),
            cache=cache,
            floor_cache=floor_cache,
            family=family,
        )

    @classmethod
    def for_files(
        cls,
        loaded,
        pattern: str,
        *,
        channel: str | None = None,
        layout: CandidateLayout | None = None,
        options: ScoreOptions | None = None,
        cache=None,
    ) -> ScoreRequest:
        """An engine's image files: ``layout`` (None: resolved from frame 0's file and
        ``channel``) decides what is read and its kind, the scored channel."""
        o = options or ScoreOptions()
        if layout is None:
            layout = candidate_layout(frame_file(pattern, 0), channel=channel)
        if o.visibility != "1-is-lit" and layout.kind != "visibility":
            raise ScoreError(
                f"--visibility {o.visibility} applies to shadow masks; this candidate is "
                f"{layout.kind}"
            )
        files = FileCandidate(
            pattern, layout, o.motion, o.visibility, _transfer(pattern, layout, o.transfer)
        )
        channel = scored_channel(layout.kind, layout.names)
        # an engine's coverage layer against the truth of the same coverage (--coverage-truth)
        if layout.kind == "coverage" and o.coverage_truth == "front":
            channel = "front_coverage"
        return cls(loaded, channel, files, options=o, cache=cache, family=_family(o, channel))

    def with_channel(self, channel: str, **changes) -> ScoreRequest:
        """This request on another channel (the same candidate, model runs shared)."""
        return replace(self, channel=channel, **changes)

    # ------------------------------------------------------------------ what it asks

    @property
    def kind(self) -> str:
        """The scored channel's kind in the metric catalogue."""
        return CHANNEL_KIND[self.channel]

    @property
    def groups(self) -> tuple[str, ...]:
        """The reference channel groups the scored channel reads."""
        return REFERENCE_GROUPS[self.channel]

    @property
    def frames(self) -> int | None:
        return self.options.frames

    @property
    def sequence(self) -> bool:
        """Frames scored as one sequence (at least two): the temporal passes may apply."""
        return bool(self.options.frames) and self.options.frames >= 2

    @property
    def is_model(self) -> bool:
        return isinstance(self.candidate, ModelCandidate)

    @property
    def is_file(self) -> bool:
        return isinstance(self.candidate, FileCandidate)

    @property
    def primary(self) -> str:
        """The family's primary channel (a model's), else the scored one."""
        return self.family.channels[0] if self.family is not None else self.channel

    @cached_property
    def frame_scenes(self) -> list:
        """The scene of every scored frame: frames 0.. of the camera path (the scene itself
        without ``frames``). The one place they are derived."""
        o = self.options
        if not o.frames:
            return [self.loaded]
        return [
            self.loaded.with_frame(k, path=o.camera_path, n_frames=o.frames)
            for k in range(o.frames)
        ]

    def candidate_frames(self) -> Callable:
        """``(frame_scene, k) -> (image, info)`` of the scored channel."""
        if self.is_model:
            return self.candidate.reader(self.channel, self.primary)
        if self.is_file:
            return self.candidate.reader(self.channel, self.primary, self.options.frames)
        return self.candidate

    def check(self) -> ScoreRequest:
        """The request checked: a :class:`ScoreError` naming what is wrong."""
        o = self.options
        if o.gate_frames is not None and not 1 <= int(o.gate_frames) <= (o.frames or 1):
            raise ScoreError(f"--gate-frames must be in [1, {o.frames or 1}], got {o.gate_frames}")
        if self.channel not in REFERENCE_GROUPS:
            raise ScoreError(
                f"channel must be one of {', '.join(REFERENCE_GROUPS)}, got {self.channel!r}"
            )
        if o.depth_buffer is not None and self.kind != "depth":
            raise ScoreError(
                f"--depth-buffer applies to a depth candidate; this one is {self.kind}"
            )
        flip_mode = str(o.flip_mode).upper()
        if flip_mode not in ("LDR", "HDR"):
            raise ScoreError(f"flip mode must be LDR or HDR, got {o.flip_mode!r}")
        if flip_mode != o.flip_mode:
            return replace(self, options=replace(o, flip_mode=flip_mode))
        return self
