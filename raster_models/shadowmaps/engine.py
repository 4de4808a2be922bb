"""The machinery every shadow-map technique shares: render the maps of a set of partitions by
casting rays at texel centres (:mod:`.render`), shade a G-buffer with them (:mod:`.shade`),
and package the outputs, cost record and diagnostics (here).

A technique module only decides *where* its maps go (a :class:`Setup`: projections, view-depth
intervals, how a pixel picks its map); rendering, depth formats, biases, filters, blending,
diagnostics and the cost record are shared, identical for all. The output images are
described in :mod:`.shade`.
"""

from __future__ import annotations

from .. import depth as _depth
from ..result import model_result
from . import filters as _filters
from .records import Setup
from .render import render_maps
from .shade import shade

__all__ = ["execute"]


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
    if params.filter == "msm":
        per = 2 if params.msm_format == "unorm16" else 4
        moment_bytes = k * r * r * 4 * per
        if params.blur_size > 1:
            moment_bytes += r * r * 4 * per  # one blur scratch texture
    rendered = sum(1 for m in maps if m is not None)
    passes = rendered
    if params.filter in (*_filters.MOMENT_FILTERS, "msm"):
        passes += rendered * (1 + (2 if params.blur_size > 1 else 0))
    return {
        "shadow_map_bytes": int(depth_bytes + moment_bytes),
        "texels_rendered": int(rendered * r * r),
        "render_passes": int(passes),
        "texture_lookups_per_pixel": float(summary["lookups_mean"]),
        "readback_latency_frames": int(setup.readback_latency),
        "compute_passes": int(setup.compute_passes),
    }


def execute(technique: str, scene, gbuf, setup: Setup, params, params_record: dict, t0: float):
    """Render, shade and package a :class:`ModelResult`."""
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
