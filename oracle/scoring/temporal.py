"""Temporal anti-aliasing metrics of a scored sequence, each frame against its own truth:
convergence and steady level, ghosting and lag on disoccluded pixels, history error where
the truth changed, flicker relative to the truth's and its per-pixel map, and the end-point
error of an engine's motion vectors (:mod:`metrics.ghosting`, :mod:`metrics.motion`).

The truth's motion and disocclusion come from a ``motion`` reference of every frame (a cheap
one: pixel-centre rays only, cached like any reference).
"""

from __future__ import annotations

import numpy as np

from ... import metrics as M
from ...metrics import video as V
from ..reference.render import ReferenceSettings
from ..reference.store import get_reference

__all__ = [
    "CONVERGENCE_WINDOW",
    "GHOSTING_WINDOW",
    "MOTION_KEYS",
    "TEMPORAL_AA_KEYS",
    "add_temporal_aa",
    "add_video_score",
    "truth_motion",
]

#: The temporal AA metrics of a sequence (:func:`add_temporal_aa`); the pass runs on the
#: channels the metric catalogue declares them for.
TEMPORAL_AA_KEYS = (
    "steady_error",
    "convergence_frames",
    "ghosting_error",
    "history_error",
    "lag_frames",
    "flicker_ratio",
)
#: The motion-vector metrics of an engine's velocity buffer.
MOTION_KEYS = (
    "motion_epe_mean",
    "motion_epe_p99",
    "motion_epe_over_half",
    "disocclusion_recall",
    "disocclusion_precision",
)

#: Frames each frame's error is averaged over before the convergence test: one jitter
#: sequence of the shortest common length (UE4, HDRP: 8), whose phase the error follows;
#: only for sequences of at least four such windows (a shorter one is judged frame by frame).
CONVERGENCE_WINDOW = 8

#: Frames after a disocclusion that count as "recently disoccluded" for ``ghosting_error``
#: (a TAA with alpha 0.1 keeps (0.9)^4 = 66% of a stale history after 4 frames).
GHOSTING_WINDOW = 4


def truth_motion(scenes_k, *, seed: int, cache, quiet: bool):
    """``(T, H, W, 2)`` motion and ``(T, H, W)`` disocclusion of the frames' references."""
    settings = ReferenceSettings(spp=1, seed=seed, channels=("motion",)).validate()
    motion, dis = [], []
    for frame_scene in scenes_k:
        ch = get_reference(frame_scene, settings, cache=cache, quiet=quiet).channels()
        motion.append(np.stack([ch["motion.X"], ch["motion.Y"]], -1))
        dis.append(ch["disocclusion"])
    return np.stack(motion).astype(np.float64), np.stack(dis) > 0.5


def _velocity(result, motion, dis, engine: list, gate_frames=None) -> dict:
    """Per-frame end-point errors of the candidate's motion vectors, and their mean over
    the judged frames (the last ``gate_frames``, else all: warm-up is not judged, as for
    every other per-frame metric)."""
    keys = MOTION_KEYS
    per = []
    for k, (frame, given) in enumerate(zip(result.frames, engine, strict=True)):
        mv, cand_dis = given
        e = M.motion_errors(motion[k], mv, disocclusion=dis[k], candidate_disocclusion=cand_dis)
        frame.metrics.update({key: e[key] for key in keys})
        if k == 0:
            frame.maps["motion_epe"] = e.pop("epe")
        per.append(e)
    out = {}
    judged = per[-(gate_frames or len(per)) :]
    for key in keys:
        vals = [e[key] for e in judged if e.get(key) is not None]
        out[key] = float(np.mean(vals)) if vals else None
    return out


def _taa_values(refs, cands, motion, dis, age, gate_frames) -> tuple[dict, dict, np.ndarray]:
    """The temporal AA metrics of candidate frames ``cands`` against ``refs``."""
    errors = M.frame_errors(refs, cands)
    window = CONVERGENCE_WINDOW if len(errors) >= 4 * CONVERGENCE_WINDOW else 1
    conv = M.convergence(errors, judged=gate_frames, window=window)
    ghost = M.ghosting(refs, cands, age, window=GHOSTING_WINDOW)
    values = {
        "steady_error": conv["steady_error"],
        "convergence_frames": conv["convergence_frames"],
        "ghosting_error": ghost["ghosting_error"],
        "history_error": M.history_error(refs, cands, motion),
        "lag_frames": ghost["lag_frames"],
        "flicker_ratio": M.flicker_ratio(refs, cands),
    }
    detail = {
        "frame_errors": [float(e) for e in errors],
        "judged_frames": int(gate_frames or len(errors)),
        "convergence_window": window,
        "ghosting_window": GHOSTING_WINDOW,
        "error_by_age": ghost["error_by_age"],
        "settled_error": ghost["settled_error"],
        "disoccluded_fraction": float(dis[1:].mean()) if len(dis) > 1 else 0.0,
    }
    return values, detail, errors


def add_temporal_aa(
    result,
    scenes_k,
    *,
    seed: int,
    cache,
    quiet: bool,
    gate_frames=None,
    engine_motion=None,
    exact_frames=None,
    display=None,
) -> tuple[dict, dict]:
    """Temporal AA metrics of a colour sequence (``result.frames``' references and
    candidates), to add to the record's summary, and a detail record; the per-pixel flicker
    map joins frame 0's maps. ``engine_motion``: per frame ``(motion (H, W, 2) in the
    oracle's convention, disocclusion (H, W) or None)``, or None. ``exact_frames``: the
    exact surrogate of every frame (the noise-floor reference): the same metrics for it join
    frame 0's noise floor (``convergence_frames`` and ``lag_frames`` excepted: counts, not
    errors). ``display``: ``(exposure, ppd)`` of the score's tone mapping: adds
    :func:`add_video_score` (``cvvdp_jod``; its detail under ``video``)."""
    refs = np.stack([f.reference for f in result.frames]).astype(np.float64)
    cands = np.stack([f.candidate for f in result.frames]).astype(np.float64)
    motion, dis = truth_motion(scenes_k, seed=seed, cache=cache, quiet=quiet)
    age = M.disocclusion_age(motion, dis)
    out, detail, _ = _taa_values(refs, cands, motion, dis, age, gate_frames)
    result.frames[0].maps["flicker"] = M.flicker_map(refs, cands)
    if engine_motion is not None and any(m is not None for m, _ in engine_motion):
        out.update(_velocity(result, motion, dis, engine_motion, gate_frames))
    if exact_frames is not None and result.frames[0].noise_floor is not None:
        exact, _, _ = _taa_values(refs, exact_frames, motion, dis, age, gate_frames)
        floor = {k: v for k, v in exact.items() if k not in ("convergence_frames", "lag_frames")}
        result.frames[0].noise_floor.update({k: v for k, v in floor.items() if v is not None})
    if display is not None:
        exposure, ppd = display
        video, detail["video"] = add_video_score(
            result,
            exposure=exposure,
            ppd=ppd,
            gate_frames=gate_frames,
            exact_frames=exact_frames,
            quiet=quiet,
        )
        out.update(video)
    return out, detail


def add_video_score(
    result, *, exposure: float, ppd: float, gate_frames=None, exact_frames=None, quiet=False
) -> tuple[dict, dict]:
    """ColorVideoVDP's JOD of the judged frames (the last ``gate_frames``, else all), both
    sequences through the one tone mapper; its noise floor joins frame 0's: the JOD of the
    exact surrogate frames (the seed-to-seed noise of the truth). Without the extra
    ``raster-oracle[video]``: null, and one line on stderr (unless ``quiet``)."""
    why = V.unavailable()
    if why is None and min(result.frames[0].reference.shape[:2]) < 2:
        why = "cvvdp_jod skipped: ColorVideoVDP needs frames of at least 2x2 pixels"
    if why is not None:
        if not quiet:
            import sys

            print(why, file=sys.stderr)
        return {"cvvdp_jod": None}, {"skipped": why}
    judged = slice(-(gate_frames or len(result.frames)), None)

    def shown(frames) -> np.ndarray:
        return np.stack([M.tonemap(f, exposure=exposure) for f in frames])[judged]

    refs = shown([f.reference for f in result.frames])
    jod = V.cvvdp_jod(refs, shown([f.candidate for f in result.frames]), ppd=ppd)
    detail = {"display": V.DISPLAY, "fps": V.FPS, "ppd": float(ppd), "frames": len(refs)}
    if exact_frames is not None and result.frames[0].noise_floor is not None:
        floor = V.cvvdp_jod(refs, shown(list(exact_frames)), ppd=ppd)
        result.frames[0].noise_floor["cvvdp_jod"] = floor
        detail["noise_floor"] = floor
    return {"cvvdp_jod": jod}, detail
