"""Soft-shadow measurements (issue 38): PCSS against the area-light truth, its contact
hardening, and light bleeding of filtered shadow maps.

- :func:`soft_scores`: error of a visibility image against the reference's ``soft_visibility``
  and ``light_fraction`` on receivers (MAE, RMSE, and the same in the reference's penumbra),
  with the reference's own noise floor (what an exact candidate scores against it).
- :func:`contact_hardening`: PCSS's penumbra width estimate (its ``penumbra_width`` output)
  against the geometric width at each receiver whose ray to the light's centre meets a
  caster, ``L t / (D - t)`` (``t`` the receiver-caster distance along that ray, ``D`` the
  receiver-light distance, ``L`` the light's size; ``2 t tan(theta / 2)`` for a sun), binned
  by the receiver-caster distance.
- :func:`umbra_bleeding`: light leaked into the hard reference's umbra (receivers with
  visibility 0): its mean and the fraction of umbra receivers above 0.1.
- :func:`soft_ranking`: PCSS at the engines' presets against PCF at fixed widths, ranked by
  their error against the area-light truth, with the noise floor.
- ``extent``: PCSS's filter extent against the geometric penumbra per preset and map field
  of view (:func:`..pcss_extent.extent_report`).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "BLEED_BLURS",
    "BLEED_FILTERS",
    "BLEED_SCENES",
    "DISTANCE_BINS",
    "MAP_RESOLUTION",
    "QUICK_BLEED_BLURS",
    "QUICK_MAP_RESOLUTION",
    "RANKED",
    "SCHEMA",
    "caster_distance",
    "contact_hardening",
    "run_soft_shadows",
    "soft_ranking",
    "soft_report",
    "soft_scores",
    "umbra_bleeding",
]

#: Receiver-caster distance bins of the contact-hardening table (scene units).
DISTANCE_BINS = (0.0, 0.1, 0.25, 0.5, 1.0, 2.0, 4.0)

#: Reference visibility below which a receiver is in the umbra; leaked light above this.
UMBRA, LEAK = 0.0, 0.1


def soft_scores(
    ref_ch: dict, vis, receivers, channels=("soft_visibility", "light_fraction"), ref2_ch=None
):
    """Per channel: ``mae``, ``rmse``, ``penumbra_mae`` (receivers whose reference value is in
    (0.02, 0.98)), ``pixels``, ``penumbra_pixels`` and the noise floors ``noise_floor`` and
    ``penumbra_noise_floor``: what an exact candidate scores, ``mean |B - A| / sqrt(2)`` with
    ``B`` the independently seeded reference ``ref2_ch`` (the scoring's exact surrogate),
    else the mean standard error of the reference (an upper bound: the truth's standard
    error has a floor where every sample agreed). A channel the reference lacks is skipped."""
    vis = np.asarray(vis, dtype=np.float64)
    rec = np.asarray(receivers, dtype=bool)
    out = {}
    for ch in channels:
        if ch not in ref_ch:
            continue
        ref = np.asarray(ref_ch[ch], dtype=np.float64)
        if ref2_ch is not None and ch in ref2_ch:
            noise = np.abs(np.asarray(ref2_ch[ch], dtype=np.float64) - ref) / math.sqrt(2.0)
        else:
            noise = np.asarray(ref_ch.get(f"{ch}_stderr", np.zeros_like(ref)), dtype=np.float64)
        err = np.abs(vis - ref)
        pen = rec & (ref > 0.02) & (ref < 0.98)
        out[ch] = {
            "mae": float(err[rec].mean()) if rec.any() else 0.0,
            "rmse": float(np.sqrt(np.mean(err[rec] ** 2))) if rec.any() else 0.0,
            "penumbra_mae": float(err[pen].mean()) if pen.any() else 0.0,
            "noise_floor": float(noise[rec].mean()) if rec.any() else 0.0,
            "penumbra_noise_floor": float(noise[pen].mean()) if pen.any() else 0.0,
            "pixels": int(rec.sum()),
            "penumbra_pixels": int(pen.sum()),
        }
    return out


def umbra_bleeding(ref_visibility, vis, receivers) -> dict:
    """Light in the hard reference's umbra: ``mean`` visibility there, ``leak_fraction`` of
    umbra receivers above 0.1, ``umbra_pixels``."""
    ref = np.asarray(ref_visibility, dtype=np.float64)
    umbra = np.asarray(receivers, dtype=bool) & (ref <= UMBRA)
    v = np.asarray(vis, dtype=np.float64)[umbra]
    return {
        "mean": float(v.mean()) if v.size else 0.0,
        "leak_fraction": float(np.mean(v > LEAK)) if v.size else 0.0,
        "umbra_pixels": int(umbra.sum()),
    }


def caster_distance(loaded, position, normal):
    """Distance from each receiver to the first caster on its ray to the light's centre
    (``inf`` where none) and the distance to the light (``inf`` for a sun), NumPy ``(N,)``."""
    from ...scenes.backend.raycast import intersect

    light = loaded.light
    p = np.asarray(position, dtype=np.float64)
    n = np.asarray(normal, dtype=np.float64)
    if light.is_directional:
        d = np.broadcast_to(-np.asarray(light.direction, dtype=np.float64), p.shape)
    else:
        d = np.asarray(light.position, dtype=np.float64) - p
        d = d / np.maximum(np.linalg.norm(d, axis=1), 1e-300)[:, None]
    side = np.where(np.sum(n * d, axis=1) >= 0, 1.0, -1.0)
    scale = 1.0 + np.sum(np.abs(n) * np.abs(p), axis=1)
    origin = p + n * (side * scale * 1e-4)[:, None]
    if light.is_directional:
        far = np.full(len(p), np.inf)
        tmax = None
    else:
        # from the offset origin, stopping short of the light (its own shape is in the scene)
        to = np.asarray(light.position, dtype=np.float64) - origin
        far = np.linalg.norm(to, axis=1)
        d = to / np.maximum(far, 1e-300)[:, None]
        tmax = np.maximum((far - light.shadow_end) * (1.0 - 1e-3), 0.0)
    hit = intersect(loaded, origin, d, tmax=tmax)
    t = np.where(hit["valid"], hit["t"].astype(np.float64), np.inf)
    return t, far


def contact_hardening(loaded, result, *, bins=DISTANCE_BINS) -> dict:
    """PCSS's penumbra width estimate against the geometric width, binned by the
    receiver-caster distance (see the module docstring). ``result``: a ``pcss`` model result
    on ``loaded``. Rows: ``lo``, ``hi``, ``pixels``, ``true_width`` (mean), ``abs_error``
    (mean ``|estimate - true|``), ``rel_error`` (``abs_error / true_width``), ``missed``
    (fraction of those receivers where the blocker search found no blocker)."""
    from ...raster_models.gbuffer import trace_gbuffer

    pcss = result.diagnostics["pcss"]
    gbuf = trace_gbuffer(loaded)
    rec = gbuf.receiver
    est = np.asarray(result.outputs["penumbra_width"], dtype=np.float64).ravel()[rec]
    t, far = caster_distance(loaded, gbuf.position[rec], gbuf.normal[rec])
    light = loaded.light
    occluded = np.isfinite(t)
    if light.is_directional:
        true = 2.0 * t * math.tan(math.radians(pcss["light_angle"]) / 2.0)
    else:
        true = pcss["light_size"] * t / np.maximum(far - t, 1e-12)
    rows = []
    for lo, hi in zip(bins[:-1], bins[1:], strict=True):
        sel = occluded & (t >= lo) & (t < hi)
        if not sel.any():
            rows.append({"lo": lo, "hi": hi, "pixels": 0})
            continue
        err = np.abs(est[sel] - true[sel])
        tw = float(true[sel].mean())
        rows.append(
            {
                "lo": lo,
                "hi": hi,
                "pixels": int(sel.sum()),
                "true_width": tw,
                "abs_error": float(err.mean()),
                "abs_error_stderr": float(err.std(ddof=1) / math.sqrt(err.size))
                if err.size > 1
                else 0.0,
                "rel_error": float(err.mean() / tw) if tw > 0 else None,
                "missed": float(np.mean(est[sel] <= 0.0)),
            }
        )
    return {"bins": rows, "occluded_receivers": int(occluded.sum()), **pcss}


#: Configurations :func:`soft_ranking` compares: PCSS at the engines' presets against PCF of
#: fixed widths (N x N taps, Poisson discs) and the hard 2x2 hardware PCF.
RANKED = (
    ("pcss (nvidia)", "pcss", {"preset": "nvidia"}),
    ("pcss (hdrp)", "pcss", {"preset": "hdrp"}),
    ("pcss (hdrp, light_range=10)", "pcss", {"preset": "hdrp", "light_range": 10.0}),
    ("pcss (nvidia, radius_scale=0.5)", "pcss", {"preset": "nvidia", "radius_scale": 0.5}),
    ("hw_pcf 2x2", "shadow-map", {"filter": "hw_pcf"}),
    ("pcf 5x5", "shadow-map", {"filter": "pcf", "pcf_size": 5}),
    ("pcf 9x9", "shadow-map", {"filter": "pcf", "pcf_size": 9}),
    ("pcf 15x15", "shadow-map", {"filter": "pcf", "pcf_size": 15}),
    ("poisson 16 taps, 16 texels", "shadow-map", {"filter": "poisson", "filter_size": 16.0}),
    ("poisson 16 taps, 48 texels", "shadow-map", {"filter": "poisson", "filter_size": 48.0}),
)


def soft_ranking(
    loaded, ref_ch: dict, *, ref2_ch=None, resolution: int = 2048, run=None, configs=RANKED
):
    """Every configuration of ``configs`` on ``loaded``, scored against the reference's
    ``soft_visibility`` and ``light_fraction`` (:func:`soft_scores`), ranked by the MAE
    against ``light_fraction`` (what PCSS estimates). A neighbour whose MAE differs by less
    than the larger noise floor is marked ``separated: False``. ``run(technique, loaded,
    **params)``: the model runner (default ``raster_models.run``); ``ref2_ch``: the
    independently seeded reference of the noise floors (:func:`soft_scores`)."""
    from ... import raster_models
    from ..scoring.score import reference_receivers

    run = run or raster_models.run
    rec = reference_receivers(ref_ch, loaded.light)
    rows = []
    for label, tech, params in configs:
        res = run(tech, loaded, resolution=resolution, **params)
        scores = soft_scores(ref_ch, res.outputs["visibility"], rec, ref2_ch=ref2_ch)
        rows.append(
            {
                "label": label,
                "technique": tech,
                "params": params,
                "lookups": res.cost.get("texture_lookups_per_pixel"),
                **scores,
            }
        )
    key = "light_fraction" if all("light_fraction" in r for r in rows) else "soft_visibility"
    rows.sort(key=lambda r: r.get(key, {}).get("mae", math.inf))
    for a, b in zip(rows, rows[1:], strict=False):
        fa, fb = a.get(key, {}), b.get(key, {})
        floor = max(fa.get("noise_floor", 0.0), fb.get("noise_floor", 0.0))
        b["separated"] = abs(fb.get("mae", 0.0) - fa.get("mae", 0.0)) >= floor
    return {"ranked_by": f"{key} mae", "rows": rows}


#: Moment filters of the bleeding table: (label, technique, parameters).
BLEED_FILTERS = (
    ("VSM", "shadow-map", {"filter": "vsm"}),
    ("EVSM2", "shadow-map", {"filter": "evsm2"}),
    ("EVSM4", "shadow-map", {"filter": "evsm4"}),
    ("MSM 16-bit", "msm", {}),
    ("MSM float32", "msm", {"msm_format": "float32"}),
)
#: Scenes and moment blurs of the bleeding table.
BLEED_SCENES = ("stacked-casters", "plate")
BLEED_BLURS = (1, 5, 9)
#: Shadow-map resolution of every model run of the study.
MAP_RESOLUTION = 2048
#: The quick form's (the main job's: about a minute on 2 loaded cores): smaller maps, fewer
#: blurs.
QUICK_MAP_RESOLUTION, QUICK_BLEED_BLURS = 1024, (1, 5)

SCHEMA = "raster-oracle.studies.soft-shadows/1"


def _bleeding(ctx, *, size, resolution: int, blurs) -> dict:
    from ... import metrics as M
    from ... import raster_models, scenes
    from ..scoring.score import reference_receivers

    rows, floors = [], {}
    for name in BLEED_SCENES:
        loaded = scenes.load(name, width=size[0], height=size[1])
        ref = ctx(loaded, ("visibility", "id", "normal", "position"), 0)
        ref2 = ctx(loaded, ("visibility", "id", "normal", "position"), 1)
        rec = reference_receivers(ref, loaded.light)
        floors[name] = float(np.abs(ref["visibility"] - ref2["visibility"])[rec].mean()) / (
            math.sqrt(2.0)
        )
        for blur in blurs:
            for label, tech, params in BLEED_FILTERS:
                res = raster_models.run(
                    tech, loaded, resolution=resolution, blur_size=blur, **params
                )
                vis = np.clip(np.asarray(res.outputs["visibility"], np.float32), 0.0, 1.0)
                sm = M.shadow_metrics(ref["visibility"], vis, receivers=rec)
                rows.append(
                    {
                        "scene": name,
                        "blur": blur,
                        "filter": label,
                        **umbra_bleeding(ref["visibility"], vis, rec),
                        "misclassified": sm["misclassified_fraction"],
                        "visibility_mae": sm["visibility_mae"],
                        "bytes": res.cost["shadow_map_bytes"],
                    }
                )
    return {"scenes": list(BLEED_SCENES), "rows": rows, "visibility_mae_floor": floors}


def soft_report(*, cache=None, quick: bool = True, quiet: bool = True, size=None) -> dict:
    """The study's record: PCSS against fixed-width PCF on ``soft-contact`` (the area-light
    truth), PCSS's contact hardening there, and the light bleeding of VSM, EVSM and MSM on
    ``stacked-casters`` and the plate. ``quick``: 160x90 px at 16 spp, 1024^2 maps, blurs 1
    and 5 (the main job), otherwise 320x180 at 32, 2048^2 maps, blurs 1, 5 and 9; ``size``
    overrides the film size (tests)."""
    from ... import raster_models, scenes
    from ..reference.render import ReferenceSettings, render_reference
    from ..reference.store import get_reference
    from .pcss_extent import extent_report

    w, h, spp = (160, 90, 16) if quick else (320, 180, 32)
    maps = QUICK_MAP_RESOLUTION if quick else MAP_RESOLUTION
    blurs = QUICK_BLEED_BLURS if quick else BLEED_BLURS
    if size is not None:
        w, h = (int(v) for v in size)

    def reference(loaded, groups, seed):
        settings = ReferenceSettings(spp=spp, seed=seed, channels=tuple(groups)).validate()
        if cache is None:
            return render_reference(loaded, settings, quiet=True)[0]
        return get_reference(loaded, settings, cache=cache, quiet=quiet).channels()

    contact = scenes.load("soft-contact", width=w, height=h)
    groups = ("soft", "edge", "id", "normal", "position")
    ref, ref2 = reference(contact, groups, 0), reference(contact, groups, 1)
    ranking = soft_ranking(contact, ref, ref2_ch=ref2, resolution=maps)
    hardening = {
        preset: contact_hardening(
            contact, raster_models.run("pcss", contact, resolution=maps, preset=preset)
        )
        for preset in ("nvidia", "hdrp")
    }
    return {
        "schema": SCHEMA,
        "quick": quick,
        "resolution": [w, h],
        "reference_spp": spp,
        "map_resolution": maps,
        "ranking": {"scene": "soft-contact", **ranking},
        "contact_hardening": {"scene": "soft-contact", "presets": hardening},
        "bleeding": _bleeding(reference, size=(w, h), resolution=maps, blurs=blurs),
        "extent": extent_report(),
    }


def run_soft_shadows(out, *, cache=None, quiet: bool = True, quick: bool = True, size=None):
    """:func:`soft_report`, written as ``out/soft_shadows.json`` and ``.html`` when ``out``
    is given; returns the record."""
    from ...reports.sections import soft_shadows_section
    from .output import write_study

    data = soft_report(cache=cache, quick=quick, quiet=quiet, size=size)
    if out is not None:
        section = soft_shadows_section(data)
        write_study(out, name="soft_shadows", data=data, section=section, title="Soft shadows")
    return data
