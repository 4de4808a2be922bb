"""Benchmarks printing machine-independent ratios measured in one run.

``bench_oracle``: the oracle's visibility reference on the city scene against a bare Dr.Jit
loop of ``ray_intersect`` + ``ray_test`` on the same rays (generated beforehand and not timed,
chunked the same way), and adaptive against uniform sampling for the same maximum standard
error.
"""

from __future__ import annotations

import time

import numpy as np

from scenes import backend

__all__ = ["bench_oracle"]


def _bare_loop(loaded, spp: int, seed: int) -> tuple[float, int]:
    """Time intersect + shadow test on the oracle's own sample rays; returns (seconds, rays)."""
    mi = backend.mitsuba()
    import drjit as dr

    from scenes.raycast import camera_rays_dr, shadow_ray_dr

    from .reference import SAMPLES_PER_CHUNK, grid_shape

    w, h = loaded.width, loaded.height
    npix = w * h
    m, n = grid_shape(spp)
    per_chunk = max(1, SAMPLES_PER_CHUNK // spp)
    light = loaded.light
    wl = mi.Vector3f(*[-float(c) for c in light.direction])
    seconds, rays = 0.0, 0
    seed_state = mi.UInt64(
        np.uint64(0x853C49E6748FEA9B) ^ np.uint64(seed * 0x9E3779B97F4A7C15 % (1 << 64))
    )
    for start in range(0, npix, per_chunk):
        count = min(per_chunk, npix - start) * spp
        idx = dr.arange(mi.UInt32, count)
        local = idx // spp
        s = idx - local * spp
        pix = local + start
        rng = mi.PCG32(
            size=count, initstate=seed_state, initseq=mi.UInt64(pix) * (1 << 24) + mi.UInt64(s)
        )
        u, v = rng.next_float32(), rng.next_float32()
        x = mi.Float(pix % w) + (mi.Float(s % m) + u) * (1.0 / m)
        y = mi.Float(pix // w) + (mi.Float(s // m) + v) * (1.0 / n)
        ray = camera_rays_dr(loaded.camera, x, y)
        dr.eval(ray)
        dr.sync_thread()
        t0 = time.perf_counter()
        si = loaded.mi_scene.ray_intersect(ray, ray_flags=mi.RayFlags.All, coherent=True)
        nrm = si.sh_frame.n
        nrm = dr.select(dr.dot(nrm, ray.d) > 0, -nrm, nrm)
        active = si.is_valid() & (dr.dot(nrm, wl) > 0.0)  # the oracle's shadow-ray candidates
        hit = loaded.mi_scene.ray_test(shadow_ray_dr(light, si.p, si.n, wl), active)
        dr.eval(hit, active)
        dr.sync_thread()
        seconds += time.perf_counter() - t0
        tested = dr.count(active)
        rays += count + int(tested[0])
    return seconds, rays


def bench_oracle(
    *, width: int = 1920, height: int = 1080, spp: int = 32, quiet: bool = True
) -> dict:
    """Oracle throughput against the bare Dr.Jit loop, and adaptive sampling's saving."""
    import scenes

    from .reference import ReferenceSettings, render_reference

    loaded = scenes.load("city", width=width, height=height)
    # warm-up: compile the kernels once so neither side pays for it
    warm = scenes.load("city", width=64, height=36)
    render_reference(warm, ReferenceSettings(spp=spp, channels=("visibility",)), quiet=True)
    _bare_loop(warm, spp, 0)

    _, stats = render_reference(
        loaded, ReferenceSettings(spp=spp, channels=("visibility",)), quiet=quiet
    )
    bare_s, bare_rays = _bare_loop(loaded, spp, 0)
    oracle_mrays = stats["mrays_per_second"]
    bare_mrays = bare_rays / bare_s / 1e6
    adaptive = ReferenceSettings(
        adaptive=True, adaptive_spp=16, target_stderr=0.02, max_spp=1024, channels=("visibility",)
    )
    _, astats = render_reference(loaded, adaptive, quiet=quiet)
    a = astats["adaptive"]
    return {
        "scene": "city",
        "resolution": [width, height],
        "spp": spp,
        "variant": backend.active().variant,
        "oracle": {
            "rays": stats["rays_cast"],
            "seconds": stats["wall_seconds"],
            "mrays_per_second": oracle_mrays,
        },
        "bare_drjit_loop": {"rays": bare_rays, "seconds": bare_s, "mrays_per_second": bare_mrays},
        "oracle_over_bare_ratio": oracle_mrays / bare_mrays,
        "oracle_over_bare_target": ">= 0.8",
        "adaptive": {
            "target_stderr": a["target_stderr"],
            "achieved_max_stderr": a["achieved_max_stderr"],
            "samples": a["samples"],
            "uniform_spp_for_same_max_stderr": a["uniform_spp_for_same_max_stderr"],
            "uniform_samples": a["uniform_samples"],
            "rays_ratio_vs_uniform": a["rays_ratio_vs_uniform"],
            "target": "<= 0.35",
            "seconds": astats["wall_seconds"],
        },
    }


def bench_models(
    *, width: int = 1920, height: int = 1080, spp: int = 32, quiet: bool = True
) -> dict:
    """SDSM (4 partitions of 2048^2, PCF 3x3) against the oracle's 32-spp visibility."""
    import raster_models
    import scenes

    from .reference import ReferenceSettings, render_reference

    params = {"partitions": 4, "resolution": 2048, "filter": "pcf", "pcf_size": 3}
    warm = scenes.load("city", width=64, height=36)
    raster_models.run("sdsm", warm, **params)
    render_reference(warm, ReferenceSettings(spp=spp, channels=("visibility",)), quiet=True)
    loaded = scenes.load("city", width=width, height=height)
    t0 = time.perf_counter()
    res = raster_models.run("sdsm", loaded, **params)
    model_s = time.perf_counter() - t0
    _, stats = render_reference(
        loaded, ReferenceSettings(spp=spp, channels=("visibility",)), quiet=quiet
    )
    return {
        "scene": "city",
        "resolution": [width, height],
        "sdsm": {"params": params, "seconds": model_s, "cost": res.cost},
        "oracle_visibility": {
            "spp": spp,
            "seconds": stats["wall_seconds"],
            "rays": stats["rays_cast"],
        },
        "sdsm_over_oracle_ratio": model_s / stats["wall_seconds"],
        "target": "<= 1.0",
        "variant": backend.active().variant,
    }
