"""The machinery every shadow-map technique shares: render the maps of a set of partitions by
casting rays at texel centres (:mod:`.render`), shade a G-buffer with them (:mod:`.shade`),
and package the outputs, cost record and diagnostics (here).

A technique module only decides *where* its maps go (a :class:`Setup`: projections, view-depth
intervals, how a pixel picks its map); rendering, depth formats, biases, filters, blending,
diagnostics and the cost record are shared, identical for all. The output images are
described in :mod:`.shade`.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .. import depth as _depth
from ..errors import ModelError
from ..result import model_result
from . import filters as _filters
from .engine_matrix import load_light_matrix, projection_from_matrix
from .faces import wound_normals
from .records import Setup
from .render import render_maps
from .shade import shade

__all__ = ["engine_conventions", "execute"]


def _cost(setup: Setup, maps, params, summary) -> dict:
    """The technique's GPU budget (not the model's run time).

    - ``shadow_map_bytes``: a depth map per partition, allocated whether a partition is empty
      or not (SDSM's constant memory), plus VSM/EVSM moment maps and one blur scratch texture;
    - ``texels_rendered``: ``R^2`` per map actually rendered;
    - ``render_passes``: shadow depth passes, plus per map a moment conversion and two
      separable blur passes for VSM/EVSM/MSM;
    - ``texture_lookups_per_pixel``: sample instructions per receiver, averaged (``N^2`` for
      NxN PCF, ``taps`` for Poisson, blocker plus filter taps for PCSS, twice in a cascade
      blend band);
    - ``readback_latency_frames``: frames between the depth used and the frame shaded;
    - ``compute_passes``: compute dispatches of the partition set-up (SDSM reductions).
    """
    r = params.resolution
    k = len(setup.partitions)
    depth_bytes = k * r * r * _depth.bytes_per_texel(params.format)
    moment_bytes = 0
    if params.filter in _filters.MOMENT_FILTERS:
        channels = 2 if params.filter in ("vsm", "evsm2") else 4
        per = 2 if params.moment_format == "float16" else 4
        moment_bytes = k * r * r * channels * per
        if params.blur_size > 1:
            moment_bytes += r * r * channels * per  # one blur scratch texture
    if params.filter == "three_vsm":
        # RG16F map plus its RG16F blur pass target (the D32F depth is counted above).
        moment_bytes = k * r * r * 2 * 2 + r * r * 2 * 2
    if params.filter == "msm":
        per = 2 if params.msm_format == "unorm16" else 4
        moment_bytes = k * r * r * 4 * per
        if params.blur_size > 1:
            moment_bytes += r * r * 4 * per  # one blur scratch texture
    rendered = sum(1 for m in maps if m is not None)
    passes = rendered
    if params.filter in (*_filters.MOMENT_FILTERS, "msm"):
        passes += rendered * (1 + (2 if params.blur_size > 1 else 0))
    if params.filter == "three_vsm":
        passes += rendered * 2  # the vertical pass reads the depth itself (no conversion)
    return {
        "shadow_map_bytes": int(depth_bytes + moment_bytes),
        "texels_rendered": int(rendered * r * r),
        "render_passes": int(passes),
        "texture_lookups_per_pixel": float(summary["lookups_mean"]),
        "readback_latency_frames": int(setup.readback_latency),
        "compute_passes": int(setup.compute_passes),
    }


def engine_conventions(technique: str, scene, gbuf, setup: Setup, params):
    """The G-buffer and set-up with the engine conventions of ``params`` applied: the
    engine's own light matrix (``light_matrix``) in place of the fitted map, and the wound
    vertex normal (``normal_offset_direction="vertex"``) as the normal-offset direction."""
    path = getattr(params, "light_matrix", "")
    if path:
        parts = setup.partitions
        if scene.light.kind != "directional" or len(parts) != 1 or parts[0].projection is None:
            raise ModelError(
                f"{technique}: light_matrix replaces the one orthographic map of a "
                f"directional light; this set-up has {len(parts)} map(s) for a "
                f"{scene.light.kind} light"
            )
        proj = projection_from_matrix(
            load_light_matrix(path), params.resolution, params.matrix_precision
        )
        if float(proj.frame.z @ np.asarray(scene.light.direction, dtype=np.float64)) <= 0.0:
            raise ModelError(
                f"light_matrix {path}: depth must grow along the light's direction "
                "(a reversed-depth matrix is not taken)"
            )
        old = parts[0]
        setup = replace(setup, partitions=[replace(old, projection=proj)])
        setup.diagnostics = dict(setup.diagnostics, light_matrix=str(path))
    if getattr(params, "normal_offset_direction", "facing") == "vertex" and params.normal_offset:
        gbuf = replace(gbuf, normal=wound_normals(scene, gbuf))
    return gbuf, setup


def execute(technique: str, scene, gbuf, setup: Setup, params, params_record: dict, t0: float):
    """Render, shade and package a :class:`ModelResult` (engine conventions applied first:
    :func:`engine_conventions`)."""
    gbuf, setup = engine_conventions(technique, scene, gbuf, setup, params)
    maps = render_maps(scene, setup, params)
    outputs, summary = shade(gbuf, setup, maps, params)
    diagnostics = dict(setup.diagnostics)
    diagnostics["partitions"] = []
    for i, part in enumerate(setup.partitions):
        rec = {
            "index": i,
            "z_begin": float(part.z_begin),
            "z_end": float(part.z_end),
            "empty": part.projection is None,
        }
        if part.projection is not None:
            rec["projection"] = part.projection.to_json()
        if maps[i] is not None:
            rec["ray_start_light_z"] = maps[i].z_start
            if maps[i].moments is not None and params.filter in _filters.MOMENT_FILTERS:
                rec["evsm_exponents"] = list(maps[i].exponents)
        rec.update(part.info)
        rec["statistics"] = summary["partitions"][i]
        diagnostics["partitions"].append(rec)
    diagnostics["split_depths"] = [float(p.z_begin) for p in setup.partitions] + [
        float(setup.partitions[-1].z_end)
    ]
    diagnostics["selection"] = setup.selection
    diagnostics["receivers"] = summary["receivers"]
    diagnostics["uncovered_receivers"] = summary["uncovered_receivers"]
    diagnostics["blended_receivers"] = summary["blended_receivers"]
    diagnostics["outside_all_partitions"] = summary["outside_all_partitions"]
    cost = _cost(setup, maps, params, summary)
    return model_result(
        technique,
        scene,
        outputs=outputs,
        cost=cost,
        diagnostics=diagnostics,
        params=params_record,
        t0=t0,
    )
