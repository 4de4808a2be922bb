"""Detection power of the conformance metrics: faults injected into an engine that claims a
shadow-map technique, scored against the claimed technique's model, beside a correct engine.

For each scene, screen size and map size, the claimed technique is ``shadow-map`` with a 3x3
PCF (``filter=pcf,pcf_size=3``), ``bias`` :data:`BIAS`, ``format=D24`` (``csm`` with the same
for the cascade fault). Three renders are compared:

- the **model**: the claimed technique in float64 (what ``score --expect`` runs);
- the **correct engine**: the same technique with ``matrix_precision=float32`` (matrices and
  lookups in 32-bit floats, as a GPU computes them): a correct implementation whose pixels
  differ from the model's only where the outcome is decided within float32 rounding;
- the **faulty engine**: the correct engine with one fault of :data:`FAULTS`.

Each is scored with the conformance metrics of ``score --expect``: the misclassified
fraction of receivers (threshold 0.5), the edge displacement (:func:`metrics.shift
.subpixel_shift`, pixels) and FLIP (shadow masks as displayed data). A fault is *caught* when
the recommended gate (:data:`RECOMMENDED_GATE`) fails it; a correct engine is *flagged*
when the gate fails it. Faults that leave the image unchanged (identical pixels) are named
``no effect`` rather than missed.
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from ... import metrics as M
from ... import raster_models, scenes
from ...metrics.shift import apply_shift, subpixel_shift
from ...raster_models.gbuffer import trace_gbuffer
from ...raster_models.params import make as make_params
from ...raster_models.shadowmaps import csm as _csm
from ...raster_models.shadowmaps.engine import execute
from ..scoring.ci.profiles import CONFORMANCE_LIMITS

__all__ = [
    "BIAS",
    "CLAIM",
    "CSM_CLAIM",
    "DEFAULT_MAPS",
    "DEFAULT_SCENES",
    "DEFAULT_SIZES",
    "FAULTS",
    "METRICS",
    "RECOMMENDED_GATE",
    "conformance_values",
    "gate_fails",
    "markdown_summary",
    "markdown_table",
    "run_cell",
    "run_detection",
    "summarize",
]

#: Constant depth bias of the claimed technique (normalized depth), as the README's gate.
BIAS = 0.002
#: What the engine claims (``--expect shadow-map:...``).
CLAIM = {"filter": "pcf", "pcf_size": 3, "bias": BIAS, "format": "D24"}
DEFAULT_SCENES = ("plate", "city", "meadow:n=100000")
DEFAULT_SIZES = ((320, 180), (1280, 720), (1920, 1080))
DEFAULT_MAPS = (1024, 2048, 4096)

#: Fault -> (what it is, how it is made).
FAULTS = {
    "one_texel_offset": "lookups one texel over in u (lookup_offset=1;0)",
    "half_texel_offset": "lookups half a texel over in u and v (lookup_offset=0.5;0.5)",
    "bias_sign_flipped": f"bias -{BIAS} instead of +{BIAS}",
    "caster_faces_swapped": "front faces cast where the claim is back faces (caster_faces)",
    "pcf_radius_off_by_one": "5x5 PCF (radius 2) where the claim is 3x3 (radius 1)",
    "cascade_one_too_far": "csm: every pixel reads the next cascade's map (4 cascades)",
    "image_shift_1px": "the image moved by 1 pixel in x",
    "image_shift_0.3px": "the image moved by 0.3 pixel in x",
}

#: The conformance metrics of ``score --expect`` for a shadow mask.
METRICS = (
    "conformance_misclassified_fraction",
    "conformance_edge_displacement_px",
    "conformance_flip_mean",
)

#: The recommended conformance gate (the ``conformance`` gate profile): a candidate fails
#: when any metric is above its value.
RECOMMENDED_GATE = dict(CONFORMANCE_LIMITS)

#: Params of each fault's faulty engine (on top of the claim; ``None``: not a model param).
_FAULT_PARAMS = {
    "one_texel_offset": {"lookup_offset": (1.0, 0.0)},
    "half_texel_offset": {"lookup_offset": (0.5, 0.5)},
    "bias_sign_flipped": {"bias": -BIAS},
    "caster_faces_swapped": {"caster_faces": "front"},
    "pcf_radius_off_by_one": {"pcf_size": 5},
}
#: Claim overrides of a fault's row (the faces fault is judged against a back-face claim).
_CLAIM_FOR = {"caster_faces_swapped": {"caster_faces": "back"}}
_CSM = {"partitions": 4}
#: The cascade row's claim (``--expect csm:...``): float32 matrices, as the engine fits.
CSM_CLAIM = {**CLAIM, **_CSM, "matrix_precision": "float32"}


def conformance_values(model, candidate, receivers, *, ppd: float = M.DEFAULT_PPD) -> dict:
    """The conformance metrics of a shadow mask ``candidate`` against ``model`` (both
    ``(H, W)`` visibility, 1 = lit) on ``receivers`` (``(H, W)`` bool), as ``score
    --expect`` computes them; ``receivers`` count of the support."""
    model = np.asarray(model, dtype=np.float32)
    cand = np.where(receivers, candidate, model).astype(np.float32)
    sm = M.shadow_metrics(model, cand, receivers=receivers, full=False)
    shift = subpixel_shift(model, cand, mask=receivers)
    flip = M.flip(model, cand, mode="LDR", ppd=ppd, tone_mapper="clip", exposure=0.0)
    return {
        "conformance_misclassified_fraction": float(sm["misclassified_fraction"]),
        "conformance_edge_displacement_px": float(shift["magnitude"]),
        "conformance_flip_mean": float(flip),
        "receivers": int(np.count_nonzero(receivers)),
        "changed_pixels": int(np.count_nonzero(receivers & (cand != model))),
    }


def gate_fails(values: dict, gate: dict | None = None) -> list[str]:
    """The gated metrics of ``values`` above their limit in ``gate`` (the recommended one by
    default)."""
    gate = RECOMMENDED_GATE if gate is None else gate
    return [k for k, lim in gate.items() if values.get(k) is not None and values[k] > lim]


def _visibility(result) -> np.ndarray:
    return np.asarray(result.outputs["visibility"], dtype=np.float32)


def _csm_runs(scene, gbuf, resolution: int) -> dict:
    """``csm`` model, correct engine and the cascade-one-too-far engine (each pixel's
    split-depth test answers the next cascade: interior split ``i`` moves to ``i - 1``).

    The claim names float32 matrices (:data:`CSM_CLAIM`): a cascade's frustum fit is itself
    float32-sensitive (on the 4-km city the float64 fit moves the texel grids by a fraction
    of a texel: edges 0.27-0.30 px, FLIP 0.05 at 320x180 with 1024^2 maps), so the model
    fits as the engine does, and the correct engine is the model."""
    params = {**CLAIM, **_CSM, "resolution": resolution, "matrix_precision": "float32"}
    correct = _visibility(raster_models.run("csm", scene, **params))
    out = {"model": correct, "correct": correct}
    values = {**CLAIM, **_CSM, "resolution": resolution, "matrix_precision": "float32"}
    p = make_params("csm", _csm.CsmParams, values)
    setup = _csm.build(scene, gbuf, p)
    parts = setup.partitions
    moved = [replace(parts[0], z_end=parts[0].z_begin)]
    moved += [replace(parts[i], z_end=parts[i - 1].z_end) for i in range(1, len(parts) - 1)]
    moved.append(parts[-1])
    faulty = replace(setup, partitions=moved)
    res = execute("csm", scene, gbuf, faulty, p, {}, time.perf_counter())
    out["cascade_one_too_far"] = _visibility(res)
    return out


def _row(scene_name, size, resolution, fault, model, correct, faulty, receivers, ppd, good):
    bad = conformance_values(model, faulty, receivers, ppd=ppd)
    effect = bad["changed_pixels"] > good["changed_pixels"] or bool(
        np.any(np.where(receivers, faulty != correct, False))
    )
    return {
        "scene": scene_name,
        "width": size[0],
        "height": size[1],
        "map": resolution,
        "fault": fault,
        "correct": good,
        "faulty": bad,
        "effect": bool(effect),
        "caught": bool(gate_fails(bad)),
        "correct_flagged": bool(gate_fails(good)),
    }


def run_cell(scene_name: str, size, resolution: int, *, faults=None, ppd=M.DEFAULT_PPD):
    """Rows of :func:`run_detection` for one scene at one screen and map size."""
    faults = list(FAULTS) if faults is None else list(faults)
    scene = scenes.load(scene_name, width=size[0], height=size[1])
    gbuf = trace_gbuffer(scene)
    receivers = gbuf.image(gbuf.receiver) > 0.5
    base = {**CLAIM, "resolution": resolution}
    cache: dict = {}

    def render(claim: dict, extra: dict, precision: str) -> np.ndarray:
        key = (tuple(sorted(claim.items())), tuple(sorted(extra.items())), precision)
        if key not in cache:
            params = {**base, **claim, **extra, "matrix_precision": precision}
            cache[key] = _visibility(raster_models.run("shadow-map", scene, **params))
        return cache[key]

    rows = []
    goods: dict = {}
    csm_runs = _csm_runs(scene, gbuf, resolution) if "cascade_one_too_far" in faults else {}
    for fault in faults:
        if fault == "cascade_one_too_far":
            model, correct = csm_runs["model"], csm_runs["correct"]
            faulty = csm_runs[fault]
        else:
            claim = _CLAIM_FOR.get(fault, {})
            model = render(claim, {}, "float64")
            correct = render(claim, {}, "float32")
            if fault.startswith("image_shift"):
                dx = 1.0 if fault == "image_shift_1px" else 0.3
                faulty = apply_shift(correct, dx, 0.0).astype(np.float32)
            else:
                faulty = render(claim, _FAULT_PARAMS[fault], "float32")
        key = id(correct)  # the correct engine's values, once per claim
        if key not in goods:
            goods[key] = conformance_values(model, correct, receivers, ppd=ppd)
        cell = (scene_name, size, resolution, fault)
        rows.append(_row(*cell, model, correct, faulty, receivers, ppd, goods[key]))
    return rows


def run_detection(
    *, scene_names=DEFAULT_SCENES, sizes=DEFAULT_SIZES, maps=DEFAULT_MAPS, faults=None, log=None
) -> dict:
    """Every fault at every (scene, screen size, map size): the table of docs/metrics.md.

    Returns ``{"claim", "gate", "rows", "summary"}``; ``summary`` counts faults caught,
    faults without effect and correct engines flagged."""
    rows = []
    for name in scene_names:
        for size in sizes:
            for resolution in maps:
                t0 = time.perf_counter()
                cell = run_cell(name, size, int(resolution), faults=faults)
                rows.extend(cell)
                if log is not None:
                    log(
                        f"detection: {name} {size[0]}x{size[1]} map {resolution}: "
                        f"{sum(r['caught'] for r in cell)}/{len(cell)} caught "
                        f"({time.perf_counter() - t0:.1f} s)"
                    )
    return {"claim": CLAIM, "gate": RECOMMENDED_GATE, "rows": rows, "summary": summarize(rows)}


def _where(r: dict) -> str:
    return f"{r['scene']} {r['width']}x{r['height']} map {r['map']}"


def summarize(rows: list[dict], gate: dict | None = None) -> dict:
    """Counts of a table's rows judged by ``gate`` (the recommended one by default; each
    row's ``caught`` and ``correct_flagged`` are set from it): faults with an effect,
    caught, missed, without effect, cells whose correct engine is flagged."""
    for r in rows:
        r["caught"] = bool(gate_fails(r["faulty"], gate))
        r["correct_flagged"] = bool(gate_fails(r["correct"], gate))
    effective = [r for r in rows if r["effect"]]
    return {
        "rows": len(rows),
        "faults_with_effect": len(effective),
        "caught": sum(r["caught"] for r in effective),
        "missed": [f"{_where(r)}: {r['fault']}" for r in effective if not r["caught"]],
        "no_effect": [f"{_where(r)}: {r['fault']}" for r in rows if not r["effect"]],
        "correct_flagged": sorted({_where(r) for r in rows if r["correct_flagged"]}),
    }


def _fmt(v: float) -> str:
    return f"{v:.4f}" if abs(v) >= 1e-4 or v == 0 else f"{v:.1e}"


def markdown_summary(record: dict, gate: dict | None = None) -> str:
    """One line per fault: for each scene, the cells where the gate caught it out of those
    where it had an effect, and the metric that caught it with the smallest margin (faulty
    value / limit) over its cells."""
    gate = RECOMMENDED_GATE if gate is None else gate
    rows = record["rows"]
    scene_names = list(dict.fromkeys(r["scene"] for r in rows))
    head = "| fault | " + " | ".join(f"`{n}`" for n in scene_names) + " |\n"
    head += "| --- |" + " --- |" * len(scene_names) + "\n"
    lines = []
    for fault in dict.fromkeys(r["fault"] for r in rows):
        cells = []
        for name in scene_names:
            mine = [r for r in rows if r["fault"] == fault and r["scene"] == name and r["effect"]]
            caught = [r for r in mine if gate_fails(r["faulty"], gate)]
            best = [max(r["faulty"][k] / lim for k, lim in gate.items()) for r in caught]
            low = f" (weakest {min(best):.2g}x its limit)" if best else ""
            cells.append(f"{len(caught)}/{len(mine)}{low}")
        lines.append(f"| {fault} | " + " | ".join(cells) + " |")
    return head + "\n".join(lines) + "\n"


def markdown_table(record: dict) -> str:
    """The detection table as Markdown: one line per (scene, size, map, fault) with the
    faulty and the correct engine's metrics and the gate's verdicts."""
    head = (
        "| scene | screen | map | fault | misclassified (faulty / correct) | edge px "
        "(faulty / correct) | FLIP (faulty / correct) | caught | correct flagged |\n"
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- |\n"
    )
    lines = []
    for r in record["rows"]:
        f, c = r["faulty"], r["correct"]
        cells = [
            f"{_fmt(f[k])} / {_fmt(c[k])}"
            for k in (
                "conformance_misclassified_fraction",
                "conformance_edge_displacement_px",
                "conformance_flip_mean",
            )
        ]
        caught = "yes" if r["caught"] else ("no effect" if not r["effect"] else "**no**")
        lines.append(
            f"| {r['scene']} | {r['width']}x{r['height']} | {r['map']} | {r['fault']} | "
            + " | ".join(cells)
            + f" | {caught} | {'**yes**' if r['correct_flagged'] else 'no'} |"
        )
    return head + "\n".join(lines) + "\n"
