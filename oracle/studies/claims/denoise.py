"""The denoiser claim (issue 46): A-SVGF's gradient-based history rejection reduces the lag of
SVGF after a light change, measured on ``flicker-rect`` against the area-light truth of every
frame (:mod:`raster_models.rtshadows`, :mod:`metrics.denoise`)."""

from __future__ import annotations

import numpy as np

from .base import NOT, PARTLY, REPRODUCED, ClaimContext, summary

__all__ = ["LAG_SCENE", "_asvgf_lag"]

#: The event scene: its light goes off and comes back on.
LAG_SCENE = "flicker-rect"


def _lags(errors, floors, off: int, on: int, steady: float) -> tuple[int | None, int | None]:
    from ....metrics.denoise import event_lag

    lag_off = event_lag(errors[:on], floors[:on], event=off, steady=steady)
    return lag_off, event_lag(errors, floors, event=on, steady=steady)


def _worse(a: int | None, b: int | None) -> bool:
    """Lag ``a`` longer than ``b`` (None: not back within the sequence, the longest)."""
    if a is None:
        return b is not None
    return b is not None and a > b


def _asvgf_lag(ctx: ClaimContext) -> dict:
    """Frames until SVGF's and A-SVGF's error is back within their lit steady error plus the
    truth's floor after the light goes off and after it comes back on."""
    from .... import scenes
    from ....metrics.denoise import frame_error_with_floor
    from ....raster_models.gbuffer import trace_gbuffer
    from ....scenes.catalogue.event_scenes import FLICKER_OFF, FLICKER_ON

    n = FLICKER_ON + 4
    base = scenes.load(LAG_SCENE, width=ctx.width, height=ctx.height, n_frames=n)
    truth, se, recv = [], [], []
    outs: dict = {"rtshadows-svgf": [], "rtshadows-asvgf": []}
    for k in range(n):
        sc = base.with_frame(k, path="static", n_frames=n)
        ref = ctx.reference(sc, channels=("soft",))
        truth.append(ref["soft_visibility"])
        se.append(ref["soft_visibility_stderr"])
        g = trace_gbuffer(sc)
        recv.append((g.receiver & g.valid).reshape(sc.height, sc.width))
        for t in outs:
            outs[t].append(ctx.run(t, sc).outputs["soft_visibility"])
    cases = []
    for t, seq in outs.items():
        err, floor = frame_error_with_floor(
            np.array(truth), np.array(seq), np.array(se), np.array(recv)
        )
        steady = float(err[FLICKER_OFF - 4 : FLICKER_OFF].mean())
        lag_off, lag_on = _lags(err, floor, FLICKER_OFF, FLICKER_ON, steady)
        cases.append(
            {
                "technique": t,
                "lag_off": lag_off,
                "lag_on": lag_on,
                "steady_error": steady,
                "errors": [float(e) for e in err],
                "floors": [float(f) for f in floor],
            }
        )
    svgf, asvgf = cases
    shorter = [_worse(svgf[k], asvgf[k]) for k in ("lag_off", "lag_on")]
    not_longer = [not _worse(asvgf[k], svgf[k]) for k in ("lag_off", "lag_on")]
    if all(not_longer) and all(shorter):
        verdict = REPRODUCED
    elif all(not_longer) and any(shorter):
        verdict = PARTLY
    else:
        verdict = NOT
    gain = np.array(svgf["errors"][FLICKER_OFF:]) - np.array(asvgf["errors"][FLICKER_OFF:])
    return {
        "value": summary(gain.tolist()),
        "value_text": "SVGF's error minus A-SVGF's in each frame from the light going off "
        "(the lags after each event, SVGF's and A-SVGF's, in the cases; None: not back "
        "within the frames judged)",
        "cases": cases,
        "verdict": verdict,
    }
