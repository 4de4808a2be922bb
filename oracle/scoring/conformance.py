"""Conformance to the technique an engine claims to implement (``score --expect``).

``--expect shadow-map:resolution=2048,filter=pcf,pcf_size=3`` names a registered technique
and its ``--set`` keys. Its model (:mod:`raster_models`) runs on every scored frame, and the
engine's image is scored against the model's output beside the truth:

- ``conformance_misclassified_fraction`` (shadow masks): receivers lit in one and shadowed
  in the other (threshold 0.5), as ``misclassified_fraction`` is against the truth;
- ``conformance_edge_displacement_px``: the sub-pixel shift of the candidate's edges from
  the model's (:func:`metrics.shift.subpixel_shift`), in pixels;
- ``conformance_flip_mean``: FLIP of the candidate against the model's image (shadow masks
  and coverage as displayed data; colour through the shared tone mapper).

A correct implementation of the claimed technique scores near 0 on all three while the truth
metrics show the technique's inherent error (a 3x3 PCF's soft edge against a hard shadow);
an implementation that reads its shadow map one texel over is displaced. The model is
deterministic: these metrics have no noise floor (a baseline compares them with a default
tolerance). Pixels whose outcome is implementation-defined (a compare within the depth
format's rounding, another surface a fraction of a pixel away) take the model's value and
are reported as fractions (:mod:`.conformance_idp`); a non-conforming shadow mask that
another ``caster_faces`` explains is named as such.
"""

from __future__ import annotations

import numpy as np

from ... import metrics as M
from ... import raster_models
from ...metrics.shift import subpixel_shift
from .conformance_idp import claimed_model, faces_diagnosis, idp_section
from .result import ScoreError

__all__ = ["CONFORMANCE_KEYS", "MIN_DISPLACEMENT_PX", "add_conformance", "parse_expect"]

#: A shadow mask misclassified beyond this against the claim is tried with the other
#: ``caster_faces`` (the recommended gate's limit).
FACES_CHECK_ABOVE = 0.001

#: Edges displaced by less than this many pixels are not named.
MIN_DISPLACEMENT_PX = 0.25

#: The metric keys conformance adds (the catalogue's ``on_request`` metrics).
CONFORMANCE_KEYS = (
    "conformance_misclassified_fraction",
    "conformance_edge_displacement_px",
    "conformance_flip_mean",
)


def parse_expect(text: str, *, kind: str | None = None) -> tuple[str, dict]:
    """``"shadow-map:resolution=2048,filter=pcf"`` -> ``("shadow-map", {parsed params})``;
    a :class:`ScoreError` for a malformed text, an unknown technique or parameter, or a
    technique that does not produce the candidate's ``kind``."""
    technique, _, rest = str(text).partition(":")
    technique = technique.strip()
    if not technique:
        raise ScoreError(f"--expect expects TECHNIQUE[:KEY=VALUE,...], got {text!r}")
    pairs: list[str] = []
    for piece in (p.strip() for p in rest.split(",")):
        if piece and ("=" in piece or not pairs):
            pairs.append(piece)
        elif piece:  # a list value (splits=0.1,0.3,0.6,1.0), as --set takes it
            pairs[-1] += f",{piece}"
    try:
        params = raster_models.parse_params(technique, pairs)
        produced = raster_models.family(technique).channels
    except raster_models.ModelError as exc:
        raise ScoreError(f"--expect {text}: {exc}") from None
    if kind is not None and kind not in produced:
        raise ScoreError(
            f"--expect {technique} produces {', '.join(produced)}; this candidate is {kind}"
        )
    return technique, params


def _frame_values(model, cand, ref, *, kind, receivers, ppd, exposure) -> dict:
    out = {}
    mask = receivers
    if kind == "visibility":
        sm = M.shadow_metrics(model, cand, receivers=receivers, full=False)
        out["conformance_misclassified_fraction"] = sm["misclassified_fraction"]
    shift = subpixel_shift(model, cand, mask=mask)
    out["conformance_edge_displacement_px"] = shift["magnitude"]
    out["conformance_shift"] = [shift["dx"], shift["dy"]]
    if kind == "color":
        out["conformance_flip_mean"] = M.flip(model, cand, mode="LDR", ppd=ppd, exposure=exposure)
    else:
        lin = dict(tone_mapper="clip", exposure=0.0)
        out["conformance_flip_mean"] = M.flip(model, cand, mode="LDR", ppd=ppd, **lin)
    return out


def add_conformance(
    result, scenes_k, expect: str, *, kind: str, ppd: float, exposure, into: dict, gate_frames=None
) -> list[str]:
    """Run the claimed technique's model on every frame scene of ``scenes_k`` and add the
    conformance metrics to each frame's metrics and (their mean over the judged frames) to
    ``into`` (the record's sections), with ``conformance`` (technique, params, per-frame
    shift ``[dx, dy]``); ``exposure``: the score's tone mapping (colour).
    Returns a note naming the displacement when the edges moved by
    :data:`MIN_DISPLACEMENT_PX` or more."""
    technique, params = parse_expect(expect, kind=kind)
    per_frame, idp, notes = [], [], []
    for frame, frame_scene in zip(result.frames, scenes_k, strict=True):
        claimed = claimed_model(technique, frame_scene, params, kind)
        model = claimed["image"]
        cand = frame.candidate
        if frame.receivers is not None:  # a mask is judged on the receivers, as the truth
            model = np.where(frame.receivers, model, frame.reference).astype(np.float32)
            cand = np.where(frame.receivers, cand, frame.reference).astype(np.float32)
        idp.append(_named_pixels(claimed, frame.receivers))
        if idp[-1] is not None:  # implementation-defined: named, not counted
            cand = np.where(idp[-1].pop("mask"), model, cand).astype(np.float32)
        values = _frame_values(
            model,
            cand,
            frame.reference,
            kind=kind,
            receivers=frame.receivers,
            ppd=ppd,
            exposure=exposure,
        )
        frame.maps["conformance_error"] = (
            np.asarray(cand, np.float64) - np.asarray(model, np.float64)
        ).astype(np.float32)
        if frame.maps["conformance_error"].ndim == 3:
            frame.maps["conformance_error"] = frame.maps["conformance_error"].mean(-1)
        frame.metrics.update({k: values.get(k) for k in CONFORMANCE_KEYS})
        per_frame.append(values)
    judged = per_frame[-(gate_frames or len(per_frame)) :]
    for key in CONFORMANCE_KEYS:
        vals = [v[key] for v in judged if v.get(key) is not None]
        into[key] = float(np.mean(vals)) if vals else None
    section = idp_section(idp)
    into["conformance"] = {
        "technique": technique,
        "params": claimed["params"],
        "shift_px": [v["conformance_shift"] for v in per_frame],
        "implementation_defined": section,
    }
    if section is not None:
        notes.append(
            f"conformance: {100 * section['fraction']:.3g} % of receivers implementation-"
            f"defined, not counted ({100 * section['depth_rounding']:.3g} % decided within "
            f"the depth format's rounding, {100 * section['other_surface']:.3g} % another "
            "surface a fraction of a pixel away)"
        )
    mis = into.get("conformance_misclassified_fraction") or 0.0
    if mis > FACES_CHECK_ABOVE and kind == "visibility":
        frame = result.frames[-1]
        cand = np.where(frame.receivers, frame.candidate, frame.reference).astype(np.float32)
        faces = faces_diagnosis(technique, scenes_k[-1], params, cand, frame.receivers, mis)
        if faces is not None:
            return [*notes, faces]
    dx, dy = np.mean([v["conformance_shift"] for v in judged], axis=0)
    if np.hypot(dx, dy) < MIN_DISPLACEMENT_PX:
        return notes
    return [
        *notes,
        f"conformance: the candidate's edges are displaced by ({dx:+.2f}, {dy:+.2f}) px from "
        f"{technique}'s model (misclassified {mis:.4g} of receivers): a filter or lookup that "
        "reads the map off by a texel, or another projection",
    ]


def _named_pixels(claimed: dict, receivers) -> dict | None:
    """The implementation-defined receivers of one frame: ``mask`` and the fractions of the
    receivers (None where the claim does not model them)."""
    rounding, other = claimed["depth_rounding"], claimed["other_surface"]
    if rounding is None or receivers is None:
        return None
    rec = np.asarray(receivers, bool)
    n = max(int(rec.sum()), 1)
    mask = (rounding | other) & rec
    return {
        "mask": mask,
        "depth_rounding": float((rounding & rec).sum()) / n,
        "other_surface": float((other & rec).sum()) / n,
        "fraction": float(mask.sum()) / n,
    }
