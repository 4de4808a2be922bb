"""How a score request is made: one options record instead of a long keyword list.

:class:`ScoreOptions` holds everything but *what* is scored (technique or candidate files)
and *where* the results go: the reference's sampling, the frames and their camera path, the
FLIP options, the platform the run stands for and the engine conventions of a candidate.
A new option (the temporal family's gate frames, motion vectors) is a new field with a
default, so no call site changes.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

from ... import metrics as M
from ..reference.settings import ExactBudget
from .result import ScoreError

__all__ = ["VISIBILITY_CONVENTIONS", "ScoreOptions"]

#: What a candidate shadow mask's 1 means: ``1-is-lit`` (the oracle's convention) or
#: ``1-is-shadowed`` (a shadow-factor buffer; read as ``1 - value``). Stated, never guessed.
VISIBILITY_CONVENTIONS = ("1-is-lit", "1-is-shadowed")


#: ``--coverage-truth`` values (:attr:`ScoreOptions.coverage_truth`).
COVERAGE_TRUTHS = ("any", "front")


@dataclass(frozen=True)
class ScoreOptions:
    """Options of a :class:`oracle.scoring.request.ScoreRequest`.

    spp, seed : the reference's samples per pixel and seed (the noise floor uses seed + 1).
    frames, camera_path : score that many frames of the camera path (None or 1: the
        scene's own frame).
    flip_mode, ppd : FLIP's mode (``LDR``/``HDR``) and pixels per degree.
    quiet : no progress bar.
    platform : the platform the run stands for (recorded; baselines are kept per platform).
    visibility : the candidate mask's convention (:data:`VISIBILITY_CONVENTIONS`).
    gate_frames : the gates judge the mean over the last N frames (None: all frames), so a
        temporal technique's warm-up neither passes nor fails a build.
    motion : an engine's motion-vector layer (``layer``, ``convention``, optional
        ``disocclusion``; :func:`oracle.scoring.inputs.frames.file_candidate`), scored against the
        reference's motion (candidates only).
    transfer : how an 8/16-bit PNG candidate's colour is decoded to linear: ``srgb``,
        ``gamma2.2`` or ``linear`` (None: ``srgb``; an EXR is linear and takes none).
    expect : ``TECHNIQUE:key=value,...``, what the engine claims to implement: its model is
        scored too, and the candidate against it (``conformance_*`` metrics;
        :mod:`oracle.scoring.conformance`).
    coverage_truth : what an engine's coverage layer is scored against: ``any`` (the
        fraction of samples any geometry covers: the reference's ``coverage``) or ``front``
        (the fraction covered by the surface seen at the pixel, an MSAA coverage mask of
        the front-most primitive: ``front_coverage``; a ground plane behind a shape makes
        ``any`` 1 on every pixel, so an all-ones mask would score perfectly against it).
    depth_buffer : a depth candidate's hyperbolic depth buffer, ``(near, far, bits)``
        (``--depth-buffer``): adds ``depth_beyond_precision_fraction``, the pixels whose
        error exceeds that buffer's rounding (None: not named, that metric is null).
    family : the technique family (``raster_models.FAMILIES``) an engine's files come from
        (candidates only; None: none): its record decides the passes as for a model's.
    exact_budget : the references' exact-coverage budget
        (:attr:`oracle.reference.settings.ReferenceSettings.exact_budget`; None: the default).
    """

    spp: int = 64
    seed: int = 0
    frames: int | None = None
    camera_path: str | None = "dolly"
    flip_mode: str = "LDR"
    ppd: float = M.DEFAULT_PPD
    quiet: bool = True
    platform: str | None = None
    visibility: str = "1-is-lit"
    gate_frames: int | None = None
    motion: dict | None = None
    transfer: str | None = None
    expect: str | None = None
    family: str | None = None
    exact_budget: object = None  # an oracle.reference.settings.ExactBudget, seconds or None
    coverage_truth: str = "any"
    depth_buffer: tuple | None = None

    def validate(self) -> ScoreOptions:
        """The options checked (a :class:`ScoreError` naming a bad one), with ``frames`` of
        1 as None and ``flip_mode`` upper-case."""
        if self.visibility not in VISIBILITY_CONVENTIONS:
            raise ScoreError(
                f"visibility must be one of {', '.join(VISIBILITY_CONVENTIONS)}, "
                f"got {self.visibility!r}"
            )
        if str(self.flip_mode).upper() not in ("LDR", "HDR"):
            raise ScoreError(f"flip mode must be LDR or HDR, got {self.flip_mode!r}")
        from .inputs.candidates import TRANSFERS

        if self.transfer is not None and self.transfer not in TRANSFERS:
            raise ScoreError(
                f"--transfer must be one of {', '.join(TRANSFERS)}, got {self.transfer!r}"
            )
        if self.coverage_truth not in COVERAGE_TRUTHS:
            raise ScoreError(
                f"--coverage-truth must be one of {', '.join(COVERAGE_TRUTHS)}, "
                f"got {self.coverage_truth!r}"
            )
        frames = self.frames if self.frames and self.frames > 1 else None
        # one exact-coverage budget for every reference of the score (frames, noise floors)
        budget = ExactBudget.of(self.exact_budget)
        flip_mode = str(self.flip_mode).upper()
        return replace(self, frames=frames, flip_mode=flip_mode, exact_budget=budget)

    def as_record(self) -> dict:
        return asdict(self)
