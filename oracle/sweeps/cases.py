"""The worker side of a sweep: one case record scored, one reference rendered into the cache.

A Dask worker (or the client, with ``workers=0``) runs :func:`run_case` and
:func:`render_reference_timed`; :class:`WorkerCache` holds what a worker process keeps from
one task to the next (loaded scenes, noise floors, the selected backend).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

from ... import raster_models
from ..errors import one_line
from ..reference.cache import ReferenceCache
from ..reference.render import ReferenceSettings
from ..reference.store import get_reference
from ..scoring.channels import METRIC_KEYS, REFERENCE_GROUPS
from ..scoring.options import ScoreOptions
from ..scoring.request import ScoreRequest
from ..scoring.technique import score_model, technique_channels
from .thumbnails import case_images

__all__ = [
    "MAX_ERROR_CHARS",
    "SEQUENCE_GATE_FRAMES",
    "WORKER_CACHE",
    "WorkerCache",
    "case_error",
    "case_phases",
    "case_scene",
    "evaluate_case",
    "reference_jobs",
    "render_reference",
    "render_reference_timed",
    "run_case",
    "run_side_task",
    "sequence_frames",
    "share_cores",
]


@dataclass
class WorkerCache:
    """What a process running sweep tasks keeps from one task to the next.

    Lifetime: the process. On a Dask worker (a process of its own, one task at a time) it
    lives as long as the worker; with ``workers=0`` and in tuning it is the client's, and
    :func:`sweep_keys` fills its scenes there too. Nothing in it changes a result: the
    scenes and noise floors are memos keyed by everything they depend on, the backend is
    selected once per process (by the variant of the sweep's first task).
    """

    #: Loaded base scenes by ``(scene, width, height, light)``; frames are derived from them.
    scenes: dict = field(default_factory=dict)
    #: Noise floors by reference and options (``floor_cache`` of
    #: :func:`oracle.scoring.score.score`).
    floors: dict = field(default_factory=dict)
    #: The Mitsuba variant this process selected (``None``: not yet selected here).
    variant: str | None = None
    #: Dr.Jit threads of this worker (its share of the cores, set by ``Client.run``), applied
    #: when the backend is selected; ``None``: Dr.Jit's default.
    threads: int | None = None

    def ensure_backend(self, variant: str | None) -> None:
        """Select ``variant`` (and this worker's thread count) once in this process."""
        if variant is None or self.variant is not None:
            return
        from ...scenes import backend

        backend.select(variant)
        self.variant = variant
        if backend.self_check() is None:  # a worker process: this machine's cached verdict
            from ..certify.verdict import cached_verdict, summary

            verdict = cached_verdict(variant)
            if verdict is not None:
                backend.set_self_check(summary(verdict))
        if self.threads is not None:
            import drjit as dr

            dr.set_thread_count(self.threads)

    def base_scene(self, rec: dict):
        """The loaded base scene of a case record (loaded once per process)."""
        from ... import scenes

        key = (rec["scene"], rec["width"], rec["height"], rec["light"])
        if key not in self.scenes:
            self.scenes[key] = scenes.load(
                rec["scene"], width=rec["width"], height=rec["height"], light=rec["light"]
            )
        return self.scenes[key]


#: This process's :class:`WorkerCache` (the one instance; its lifetime is the process's).
WORKER_CACHE = WorkerCache()

#: Longest error message kept in a failed case's row, in characters.
MAX_ERROR_CHARS = 2000


def case_error(exc: BaseException) -> str:
    """A failed case's ``error``: the exception's type and message on one line."""
    return one_line(exc, with_type=True)[:MAX_ERROR_CHARS]


def _reference_groups(technique: str) -> list[tuple[str, ...]]:
    """Channel groups of the references scoring ``technique`` reads (one per channel)."""
    return [REFERENCE_GROUPS[c] for c in technique_channels(technique)]


def share_cores(threads: int) -> None:
    """Worker set-up (``Client.run``): this worker's Dr.Jit threads, its share of the cores,
    so that the local cluster's workers do not oversubscribe the machine."""
    WORKER_CACHE.threads = max(1, int(threads))


def case_scene(rec: dict):
    """The loaded scene of a case record: its frame of its camera or light path."""
    base = WORKER_CACHE.base_scene(rec)
    if rec.get("light_path"):
        return base.with_light_frame(rec["frame"], path=rec["light_path"], n_frames=rec["n_frames"])
    if rec.get("camera_path"):
        return base.with_frame(rec["frame"], path=rec["camera_path"], n_frames=rec["n_frames"])
    return base


def reference_jobs(rec: dict) -> list[dict]:
    """The reference records a case needs: ``{"scene": ..., "channels", "seed", "spp"}``."""
    scene_part = {
        k: rec[k]
        for k in ("scene", "width", "height", "light", "camera_path", "light_path", "frame")
    }
    scene_part["n_frames"] = (
        rec["n_frames"] if rec.get("camera_path") or rec.get("light_path") else None
    )
    jobs = []
    for groups in _reference_groups(rec["technique"]):
        for seed in (rec["seed"], rec["seed"] + 1):
            jobs.append({**scene_part, "channels": list(groups), "seed": seed, "spp": rec["spp"]})
    return jobs


def render_reference(job: dict, cache_root: str, variant: str | None) -> str:
    """Worker task: render one reference into the cache (or find it there); its status."""
    WORKER_CACHE.ensure_backend(variant)
    settings = ReferenceSettings(
        spp=job["spp"], seed=job["seed"], channels=tuple(job["channels"])
    ).validate()
    rec = dict(job, n_frames=job["n_frames"] or 1)
    ref = get_reference(case_scene(rec), settings, cache=ReferenceCache(cache_root), quiet=True)
    return ref.cache_status


#: Last frames of a sequence case whose metrics are averaged (the steady state).
SEQUENCE_GATE_FRAMES = 4


def sequence_frames(rec: dict, loaded) -> int | None:
    """Frames a case scores as one sequence (None: its own frame alone): every frame of its
    camera path for a temporal family (TAA: ghosting and steady error need the sequence) and
    for any technique on a scene whose objects move (the baselines beside it)."""
    temporal = raster_models.family(rec["technique"]).temporal or bool(loaded.object_motion)
    if temporal and rec.get("camera_path") and rec.get("n_frames", 1) >= 2:
        return int(rec["n_frames"])
    return None


def evaluate_case(
    loaded,
    technique: str,
    params: dict,
    *,
    spp: int,
    seed: int,
    cache,
    images: bool = False,
    frames: int | None = None,
) -> dict:
    """Score one technique configuration on ``loaded``: metrics, noise floor, cost, params.

    Shadow techniques are scored on visibility; anti-aliasing techniques on colour with the
    coverage metrics merged in, exactly as ``raster-oracle score --technique`` does. With
    ``images``, ``"images"`` holds thumbnails (:func:`case_images`). With ``frames``, the
    frames 0.. of ``loaded``'s camera path are scored as one sequence, the per-frame metrics
    averaged over the last :data:`SEQUENCE_GATE_FRAMES` (the temporal AA metrics added).
    """
    seq = {}
    if frames:
        seq = dict(
            frames=frames,
            camera_path=loaded.camera_path,
            gate_frames=min(SEQUENCE_GATE_FRAMES, frames),
        )
    options = ScoreOptions(spp=spp, seed=seed, quiet=True, **seq)
    request = ScoreRequest.for_model(
        loaded, technique, params, options=options, cache=cache, floor_cache=WORKER_CACHE.floors
    )
    result = score_model(request)
    record = result.record
    info = record["candidate_info"][0]
    metrics = {k: record.get(k) for k in METRIC_KEYS}
    metrics["noise_floor"] = record.get("noise_floor")
    metrics["receiver_count"] = result.frames[0].metrics.get("receiver_count")
    out = {"metrics": metrics, "cost": info["cost"], "params": info["params"]}
    # the score's seconds by pass (its frames include the model runs): what the main job's
    # "metrics by pass" table sums
    out["passes"] = result.phases.record() if result.phases is not None else {}
    # the models' own seconds (each frame's run, once however many channels are scored)
    out["model_seconds"] = float(
        sum(i.get("model_seconds") or 0.0 for i in record["candidate_info"])
    )
    if images:
        t0 = time.perf_counter()
        out["images"] = case_images(result)
        out["image_seconds"] = time.perf_counter() - t0
    return out


def run_case(rec: dict, cache_root: str, variant: str | None, *_deps, images: bool = False) -> dict:
    """Worker task: evaluate one case record; never raises (a failure is a result)."""
    t0 = time.perf_counter()
    try:
        WORKER_CACHE.ensure_backend(variant)
        loaded = case_scene(rec)
        out = evaluate_case(
            loaded,
            rec["technique"],
            rec["params"],
            spp=rec["spp"],
            seed=rec["seed"],
            cache=ReferenceCache(cache_root),
            images=images,
            frames=sequence_frames(rec, loaded),
        )
        out["status"], out["error"] = "done", None
    except Exception as exc:  # recorded in the store; the sweep goes on
        out = {"status": "failed", "error": case_error(exc), "metrics": None, "cost": None}
        out["params"] = rec["params"]
    out["wall_seconds"] = time.perf_counter() - t0
    out["phases"] = case_phases(out)
    return out


def case_phases(res: dict) -> dict[str, float]:
    """A finished case's seconds by phase: ``models`` (the model runs), ``images`` (its
    thumbnails) and ``metrics`` (the rest: reading the cached references, noise floors,
    metrics)."""
    wall = float(res.get("wall_seconds") or 0.0)
    models = float(res.pop("model_seconds", 0.0) or 0.0)
    images = float(res.pop("image_seconds", 0.0) or 0.0)
    return {"models": models, "images": images, "metrics": max(0.0, wall - models - images)}


def render_reference_timed(job: dict, cache_root: str, variant: str | None) -> dict:
    """Worker task of a Dask sweep: :func:`render_reference` and its wall seconds."""
    t0 = time.perf_counter()
    status = render_reference(job, cache_root, variant)
    return {"status": status, "seconds": time.perf_counter() - t0}


def run_side_task(study, kwargs: dict, cache_root: str, variant: str | None) -> dict:
    """Worker task: one part of a study run beside the cases (the main job's sections,
    :mod:`oracle.sweeps.mainjob`), ``study(cache=..., **kwargs)``; never raises.

    Returns ``{"value", "error", "seconds"}``: the study's record (None when it raised),
    the error on one line (None when it did not) and its wall seconds.
    """
    t0 = time.perf_counter()
    try:
        WORKER_CACHE.ensure_backend(variant)
        out = {"value": study(cache=ReferenceCache(cache_root), **kwargs), "error": None}
    except Exception as exc:  # the section reports it; the job goes on
        out = {"value": None, "error": case_error(exc)}
    out["seconds"] = time.perf_counter() - t0
    return out
