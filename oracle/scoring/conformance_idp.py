"""Conformance that holds on real content: the claimed model's pixels whose outcome is
implementation-defined, and the engine conventions a failed conformance points at.

- :func:`claimed_model`: the claimed technique's output on one frame and, for a shadow mask
  of ``shadow-map``, ``csm`` or ``sdsm``, the receivers a correct engine may decide
  otherwise (:func:`raster_models.shadowmaps.probes.implementation_defined`): compares
  decided within the depth format's rounding of the map (the model's ``compare_margin``)
  and pixels where a probe 1/64 pixel away sees another surface with another verdict. The
  conformance metrics judge the rest; the fractions are reported beside them.
- :func:`faces_diagnosis`: when a shadow mask does not conform, the claim re-run with the
  other ``caster_faces``; a variant that conforms names the mismatch (three.js renders the
  back faces of single-sided materials) instead of a texel offset.
"""

from __future__ import annotations

import numpy as np

from ... import metrics as M
from ... import raster_models
from ...raster_models.params import as_dict, make
from ...raster_models.shadowmaps import SHADOW_TECHNIQUES
from ...raster_models.shadowmaps.probes import implementation_defined
from ...raster_models.shadowmaps.visibility import entry

__all__ = ["FACES", "claimed_model", "faces_diagnosis", "idp_section"]

#: ``caster_faces`` values a faces diagnosis tries.
FACES = ("both", "front", "back")
#: A variant explains the candidate when it misclassifies at most this share of the claim's.
EXPLAINS = 0.25


def claimed_model(technique: str, frame_scene, params: dict, kind: str) -> dict:
    """``{"image", "params", "depth_rounding", "other_surface"}`` of the claimed technique on
    one frame (the masks ``None`` where not modelled: other techniques and kinds)."""
    if kind == "visibility" and technique in SHADOW_TECHNIQUES:
        got = implementation_defined(frame_scene, technique, params)
        _, cls, _ = entry(technique)
        return {
            "image": np.asarray(got["outputs"]["visibility"], np.float32),
            "params": as_dict(make(technique, cls, dict(params))),
            "depth_rounding": got["depth_rounding"],
            "other_surface": got["other_surface"],
        }
    res = raster_models.run(technique, frame_scene, **params)
    return {
        "image": np.asarray(res.outputs[kind], np.float32),
        "params": res.params,
        "depth_rounding": None,
        "other_surface": None,
    }


def idp_section(per_frame: list[dict]) -> dict | None:
    """The record's ``implementation_defined``: mean fractions of the receivers (depth
    rounding, another surface, either) over the frames that model them."""
    frames = [f for f in per_frame if f is not None]
    if not frames:
        return None
    return {
        key: float(np.mean([f[key] for f in frames]))
        for key in ("depth_rounding", "other_surface", "fraction")
    }


def faces_diagnosis(technique, frame_scene, params, cand, receivers, misclassified) -> str | None:
    """A note when another ``caster_faces`` explains a non-conforming shadow mask ``cand``
    (its misclassified fraction against the variant at most :data:`EXPLAINS` of
    ``misclassified`` against the claim), else None."""
    if technique not in SHADOW_TECHNIQUES or not misclassified:
        return None
    claimed = params.get("caster_faces", "both")
    best = None
    for faces in FACES:
        if faces == claimed:
            continue
        image = raster_models.run(technique, frame_scene, **{**params, "caster_faces": faces})
        model = np.asarray(image.outputs["visibility"], np.float32)
        model = np.where(receivers, model, cand).astype(np.float32)
        got = M.shadow_metrics(model, cand, receivers=receivers)["misclassified_fraction"]
        if got <= EXPLAINS * misclassified and (best is None or got < best[1]):
            best = (faces, got)
    if best is None:
        return None
    return (
        f"conformance: the candidate casts shadows from other faces than claimed: it matches "
        f"caster_faces={best[0]} (misclassified {best[1]:.4g}, against {misclassified:.4g} "
        f"for caster_faces={claimed}); three.js renders the back faces of single-sided "
        "materials (shadowSide): claim caster_faces=back"
    )
