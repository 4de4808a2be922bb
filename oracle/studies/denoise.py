"""Ray-traced shadows denoised over frames (issue 46): each ``rtshadows`` denoiser on the
event scenes against the area-light truth of every frame, with its noise floor.

For each event scene (``flicker-*``, ``occluder-*``, ``pan-*`` along ``fast-pan``) and frame,
the reference's ``soft`` group at ``spp`` camera samples (16 light samples each) is the truth;
one set of ray-traced inputs a frame (:func:`raster_models.rtshadows.frames.build_frame`) feeds
every denoiser, so they see the same rays. Per denoiser and scene:

- ``error``: mean absolute error on receivers over the sequence's last :data:`STEADY` frames
  (the flicker scenes: the frames before the light goes off), beside ``floor``, the truth's
  mean 95 % half-interval there;
- ``lag_off`` / ``lag_on`` (flicker scenes): :func:`metrics.denoise.event_lag` after the light
  goes off (within the frames it stays off) and comes back on (judged against the lit steady
  error); the table writes ``>N`` when the error was not back within the N frames judged;
- ``ghosting``: :func:`metrics.ghosting.ghosting`'s error on pixels disoccluded within the last
  4 frames (None where nothing is disoccluded), ``ghosting_by_age`` the same by disocclusion
  age 0..3;
- ``penumbra_bias``: :func:`metrics.denoise.penumbra_width` of the last frame minus the
  truth's (pixels; positive: over-blur);
- ``added_flicker``: :func:`metrics.temporal.added_flicker` on receivers.
"""

from __future__ import annotations

import json
import time

import numpy as np

from ...metrics.denoise import event_lag, frame_error_with_floor, penumbra_width
from ...metrics.ghosting import disocclusion_age, ghosting
from ...metrics.temporal import added_flicker
from ...raster_models.rtshadows.frames import build_frame
from ...raster_models.rtshadows.model import DENOISERS, denoise_step
from ...scenes.catalogue.event_scenes import EVENT_SCENES, FLICKER_OFF, FLICKER_ON
from ...scenes.loader import load
from ..reference.render import ReferenceSettings, render_reference

__all__ = ["FRAMES", "STEADY", "denoise_table", "main", "run_denoise_study"]

#: Frames a sequence runs (the flicker comes back on at frame 12).
FRAMES = 18
#: Frames the steady error is averaged over.
STEADY = 4


def _sequence(name: str, frames: int, spp: int, denoisers) -> dict:
    path = "fast-pan" if name.startswith("pan") else None
    base = load(name, n_frames=frames)
    truth, se, recv, motion, dis = [], [], [], [], []
    outs: dict = {d: [] for d in denoisers}
    states: dict = dict.fromkeys(denoisers)
    prev = None
    for k in range(frames):
        sc = base.with_frame(k, path=path, n_frames=frames)
        ch, _ = render_reference(sc, ReferenceSettings(spp=spp, channels=("soft",)), quiet=True)
        truth.append(ch["soft_visibility"])
        se.append(ch["soft_visibility_stderr"])
        prev = build_frame(sc, k, prev)
        recv.append(prev.receiver)
        motion.append(prev.motion)
        dis.append(prev.disoccluded)
        for d in denoisers:
            out, states[d], _ = denoise_step(d, prev, states[d], None)
            outs[d].append(np.clip(np.nan_to_num(out), 0.0, 1.0))
    return {
        "truth": np.array(truth, dtype=np.float64),
        "stderr": np.array(se, dtype=np.float64),
        "receiver": np.array(recv),
        "motion": np.array(motion),
        "disoccluded": np.array(dis),
        "outputs": {d: np.array(v, dtype=np.float64) for d, v in outs.items()},
    }


def _scores(seq: dict, name: str, d: str) -> dict:
    t, s, m = seq["truth"], seq["stderr"], seq["receiver"]
    c = np.where(m, seq["outputs"][d], 0.0)
    t0 = np.where(m, t, 0.0)
    err, floor = frame_error_with_floor(t, c, s, m)
    flick = name.startswith("flicker")
    steady = slice(FLICKER_OFF - STEADY, FLICKER_OFF) if flick else slice(-STEADY, None)
    lit = float(err[steady].mean())
    # ages counted from the sequence start are not disocclusions: from frame STEADY on only
    age = disocclusion_age(seq["motion"], seq["disoccluded"])[STEADY:]
    g = ghosting(t0[STEADY:], c[STEADY:], np.where(m[STEADY:], age, 10**6))
    w_c = penumbra_width(c[-1], t[-1], mask=m[-1])
    w_t = penumbra_width(t[-1], t[-1], mask=m[-1])
    return {
        "error": lit,
        "floor": float(floor[steady].mean()),
        "errors": err.tolist(),
        "floors": floor.tolist(),
        # the light is off for frames FLICKER_OFF .. FLICKER_ON - 1 only
        "lag_off": event_lag(err[:FLICKER_ON], floor[:FLICKER_ON], event=FLICKER_OFF)
        if flick
        else None,
        "lag_on": event_lag(err, floor, event=FLICKER_ON, steady=lit) if flick else None,
        "ghosting": g["ghosting_error"],
        "ghosting_by_age": g["error_by_age"],
        "penumbra_bias": None if w_c is None or w_t is None else w_c - w_t,
        "added_flicker": added_flicker(t0, c),
    }


def run_denoise_study(*, scenes=None, frames: int = FRAMES, spp: int = 32, denoisers=None):
    """Scores ``{scene: {denoiser: record}}`` (see the module docstring) and the run's
    settings and wall time."""
    t0 = time.perf_counter()
    names = list(scenes or EVENT_SCENES)
    ds = list(denoisers or DENOISERS)
    out = {}
    for name in names:
        seq = _sequence(name, frames, spp, ds)
        out[name] = {d: _scores(seq, name, d) for d in ds}
    settings = {"frames": frames, "spp": spp, "denoisers": ds, "scenes": names}
    return {"settings": settings, "scores": out, "wall_seconds": time.perf_counter() - t0}


def _fmt(v, spec):
    return "-" if v is None else format(v, spec)


def _lag(v, frames: int) -> str:
    """A lag, or ``>N`` when the error was not back within the ``frames`` judged."""
    return f">{frames - 1}" if v is None else str(v)


def denoise_table(result: dict) -> str:
    """The Markdown table of docs/research.md: one row per scene and denoiser."""
    rows = [
        "| scene | denoiser | error (floor) | lag off / on (frames) | ghosting | penumbra "
        "bias (px) | added flicker |",
        "|---|---|---|---|---|---|---|",
    ]
    for name, per in result["scores"].items():
        for d, r in per.items():
            lag = "-"
            if name.startswith("flicker"):
                n_on = result["settings"]["frames"] - FLICKER_ON
                off = _lag(r["lag_off"], FLICKER_ON - FLICKER_OFF)
                lag = f"{off} / {_lag(r['lag_on'], n_on)}"
            rows.append(
                f"| {name} | {d} | {r['error']:.4f} ({r['floor']:.4f}) | {lag} | "
                f"{_fmt(r['ghosting'], '.4f')} | {_fmt(r['penumbra_bias'], '+.2f')} | "
                f"{r['added_flicker']:.4f} |"
            )
    return "\n".join(rows)


def main(argv=None) -> int:
    """``python -m raster_oracle.oracle.studies.denoise OUT.json [SCENE ...]``: run the study,
    write its JSON and print the table."""
    import sys

    args = list(sys.argv[1:] if argv is None else argv)
    if not args:
        print("usage: python -m raster_oracle.oracle.studies.denoise OUT.json [SCENE ...]")
        return 2
    unknown = [s for s in args[1:] if s not in EVENT_SCENES]
    if unknown:
        print(f"unknown event scene {unknown[0]!r}; choose from {', '.join(EVENT_SCENES)}")
        return 2
    result = run_denoise_study(scenes=args[1:] or None)
    with open(args[0], "w", encoding="utf-8") as fh:
        json.dump(result, fh, indent=1)
    print(denoise_table(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
