"""Anti-aliasing framebuffer memory from the models' own accounting, against the quoted figures.

Every anti-aliasing model's cost record carries ``framebuffer_bytes`` (the multisampled or
accumulation buffers, per buffer in ``framebuffer_bytes_by_buffer``) and
``resolve_target_bytes`` (the 1x target a resolve writes). Both are per-pixel layouts, so a
run on a tiny film gives exact bytes per pixel, restated here at the resolutions the seed
slides and papers talk about (1280x736, 1920x1080). :func:`memory_table` does that for a list
of configurations (RGBA8 colour + D32 depth by default: MSAA N, ACAA, AGAA K = 1, 2, ...);
:func:`compare_quoted` sets the computed figures against every figure the seeds quote
(:data:`QUOTED`) and says which are reproduced, within the rounding of the quoted value.

Baselines: the AGAA slides and paper compare with *deferred* MSAA, a per-sample G-buffer
(``msaa`` with ``shading="deferred"``, 16 bytes per sample: D32F depth, RGB10A2 normal, RGBA8
albedo/specular, RGBA8 emissive/material; :mod:`raster_models.aa.msaa`); forward MSAA (colour
+ depth per sample) stays beside it. The AGAA savings are measured against deferred MSAA.

Findings (see :func:`agaa_breakdown` and :func:`aggregate_layout_bound`):

- The model's AGAA at 1280x736 is 79.1 / 98.0 MB (K = 1 / 2, without the resolve target)
  against the slides' 41 / 71 MB: 8 x 4 bytes of depth (30.1 MB), 8 x 4 bytes of prepass
  normals (30.1 MB) and K x 20 bytes of aggregates (18.8 MB each). The slides build per-sample
  visibility with a Z-prepass ("Per-sample visibility (via Z-prepass)"): the per-sample
  normal buffer, which the model keeps for its clustering distance, is what the slides do not
  count. Without it the model gives 52.7 / 71.6 MB with the resolve target: K = 2 within a
  megabyte of the quoted 71 MB.
- The slides' 41 MB (1 aggregate) and 71 MB (2) cannot both come from any layout "N x depth +
  K x aggregate": one more aggregate costs 30 MB (31.8 bytes a pixel, against the model's 20),
  which leaves 11 MB for everything else, less than an 8x 32-bit depth buffer alone (30.1 MB).
- Deferred 8x with the 16-byte G-buffer is 120.6 MB (115.0 MiB; 124.4 MB with the 1x target)
  against the quoted 112 MB (14.9 bytes a sample): the slides give no layout.

References
----------
C. Wyman, High-quality rasterization (NVIDIA slides, 2015): AGAA memory 41 / 71 / 112 MB.
C. Crassin, M. McGuire, K. Fatahalian, A. Lefohn, Aggregate G-Buffer Anti-Aliasing, I3D 2015,
doi:10.1145/2699276.2699285 (abstract: 30 % less memory than 8x MSAA, 45 % for 16x).
E. Enderton, E. Lum, C. Rouet, O. Kouznetsov, Accumulative anti-aliasing (ACAA), NVIDIA:
half the multisample framebuffer memory.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ...reports.sections import aa_memory_section
from ..scoring.output import MEMORY_RESOLUTIONS
from .output import write_study

__all__ = [
    "DEFAULT_CONFIGS",
    "MEMORY_RESOLUTIONS",
    "QUOTED",
    "Config",
    "Quote",
    "aggregate_layout_bound",
    "agaa_breakdown",
    "compare_quoted",
    "memory_report",
    "memory_table",
    "summary_lines",
    "write_memory_report",
]

#: Film size of the accounting runs (any size gives the same bytes per pixel).
_PROBE_SIZE = (8, 6)
#: Scene of the accounting runs (a directional light, which every AA model takes).
_PROBE_SCENE = "star"


@dataclass(frozen=True)
class Config:
    """One row of the table: a label, a technique and its parameters."""

    label: str
    technique: str
    params: dict = field(default_factory=dict)


_RGBA8_D32 = {"color_format": "rgba8", "depth_format": "D32F"}

#: RGBA8 colour + D32 depth (float) wherever the model has the choice.
DEFAULT_CONFIGS: tuple[Config, ...] = (
    Config("no AA", "noaa"),
    *(Config(f"MSAA {n}x", "msaa", {"samples": n, **_RGBA8_D32}) for n in (2, 4, 8, 16)),
    *(
        Config(f"Deferred MSAA {n}x", "msaa", {"samples": n, "shading": "deferred", **_RGBA8_D32})
        for n in (4, 8, 16)
    ),
    Config("SSAA 8x", "ssaa", {"samples": 8}),
    Config("ACAA 8x (RGBA8 accumulation)", "acaa", {"samples": 8, "accumulation": "rgba8"}),
    Config("ACAA 8x (float accumulation)", "acaa", {"samples": 8, "accumulation": "float32"}),
    Config("ACAA 16x (RGBA8 accumulation)", "acaa", {"samples": 16, "accumulation": "rgba8"}),
    Config("AGAA 8x, 1 aggregate", "agaa", {"samples": 8, "aggregates": 1}),
    Config("AGAA 8x, 2 aggregates", "agaa", {"samples": 8, "aggregates": 2}),
    Config("AGAA 16x, 2 aggregates", "agaa", {"samples": 16, "aggregates": 2}),
    Config("FXAA", "fxaa"),
    *(Config(f"SMAA {m}", "smaa", {"mode": m}) for m in ("1x", "t2x", "s2x", "4x")),
)


@dataclass(frozen=True)
class Quote:
    """A figure the seeds quote.

    ``kind`` is ``"bytes"`` (``value`` in MB of the source, ``resolution`` given) or
    ``"ratio"`` (``value`` is ``1 - a / b`` for ``"saving"``, ``a / b`` for ``"fraction"``);
    ``a`` and ``b`` are labels of :data:`DEFAULT_CONFIGS` (``b`` ``None`` for bytes);
    ``decimals`` is how the source rounded the value (0: whole MB; 2: whole percent);
    ``from_quotes`` names two byte quotes whose own ratio the value should match.
    """

    key: str
    text: str
    source: str
    kind: str
    value: float
    a: str
    b: str | None = None
    resolution: tuple[int, int] | None = None
    decimals: int = 0
    note: str = ""
    from_quotes: tuple[str, str] | None = None


_SLIDES = "Wyman 2015, High-quality rasterization slides (seed 001), AGAA results"
_DEFERRED = (
    "deferred 8x MSAA (the slides' baseline): a per-sample 16-byte G-buffer (msaa "
    "shading=deferred); the slides give no layout"
)

#: Every memory figure the seeds quote, with the computed configuration it is set against.
QUOTED: tuple[Quote, ...] = (
    Quote(
        "agaa_1a_mb",
        "AGAA (1A): Memory 41 MB, 1280x736",
        _SLIDES,
        "bytes",
        41.0,
        "AGAA 8x, 1 aggregate",
        resolution=(1280, 736),
    ),
    Quote(
        "agaa_2a_mb",
        "AGAA (2A): Memory 71 MB, 1280x736",
        _SLIDES,
        "bytes",
        71.0,
        "AGAA 8x, 2 aggregates",
        resolution=(1280, 736),
    ),
    Quote(
        "deferred_8x_mb",
        "Deferred 8x (reference): Memory 112 MB, 1280x736",
        _SLIDES,
        "bytes",
        112.0,
        "Deferred MSAA 8x",
        resolution=(1280, 736),
        note=_DEFERRED,
    ),
    Quote(
        "agaa_2a_saving_slides",
        "37% less memory with 2 aggregates vs 8x MSAA (super-sampled G-buffer)",
        _SLIDES + " ('Results: memory')",
        "ratio",
        0.37,
        "AGAA 8x, 2 aggregates",
        "Deferred MSAA 8x",
        decimals=2,
        note=_DEFERRED,
        from_quotes=("agaa_2a_mb", "deferred_8x_mb"),
    ),
    Quote(
        "agaa_2a_saving_8x",
        "2 aggregates: 30% less memory than 8x MSAA",
        "Crassin et al. 2015, abstract",
        "ratio",
        0.30,
        "AGAA 8x, 2 aggregates",
        "Deferred MSAA 8x",
        decimals=2,
        note=_DEFERRED,
    ),
    Quote(
        "agaa_2a_saving_16x",
        "2 aggregates: 45% savings for 16x MSAA",
        "Crassin et al. 2015, abstract",
        "ratio",
        0.45,
        "AGAA 16x, 2 aggregates",
        "Deferred MSAA 16x",
        decimals=2,
        note="deferred 16x MSAA: the same 16-byte G-buffer per sample",
    ),
    Quote(
        "acaa_fraction",
        "ACAA: half the multisample framebuffer memory",
        "Enderton et al., ACAA (TECHNIQUES.md); Wyman 2015 slides: 'less memory (in color buffer)'",
        "ratio",
        0.5,
        "ACAA 8x (RGBA8 accumulation)",
        "MSAA 8x",
        decimals=1,
    ),
)


def _probe_scene():
    from ... import scenes

    w, h = _PROBE_SIZE
    return scenes.load(_PROBE_SCENE, width=w, height=h)


def _per_pixel(total: int, n_pix: int, what: str) -> int:
    per, rest = divmod(int(total), n_pix)
    if rest:
        raise ValueError(
            f"{what} ({total} bytes on {n_pix} pixels) is not a whole per-pixel layout"
        )
    return per


def memory_table(
    configs=DEFAULT_CONFIGS, *, resolutions=MEMORY_RESOLUTIONS, scene=None
) -> list[dict]:
    """Framebuffer bytes of each configuration, from the model's own cost record.

    Each model runs once on a tiny film (:data:`_PROBE_SIZE` of the ``star`` scene, or
    ``scene``); its ``framebuffer_bytes_by_buffer`` and ``resolve_target_bytes``, divided by
    the film's pixels, are restated at every resolution.

    Returns
    -------
    list of dict
        One row per configuration: ``label``, ``technique``, ``params`` (every parameter as
        the model ran), ``bytes_per_pixel`` (``buffer -> bytes``, with ``resolve`` for the 1x
        resolve target and ``total``), ``framebuffer_bytes_per_pixel`` (without the resolve
        target, the models' ``framebuffer_bytes``) and ``at``: ``"WxH" -> {"framebuffer_bytes",
        "total_bytes", "framebuffer_MB", "total_MB", "framebuffer_MiB", "total_MiB"}``.
    """
    from ... import raster_models

    loaded = scene or _probe_scene()
    n_pix = loaded.width * loaded.height
    rows = []
    for cfg in configs:
        result = raster_models.run(cfg.technique, loaded, **cfg.params)
        cost = result.cost
        per = {
            name: _per_pixel(b, n_pix, f"{cfg.label} {name} buffer")
            for name, b in cost["framebuffer_bytes_by_buffer"].items()
            if b
        }
        fb = _per_pixel(cost["framebuffer_bytes"], n_pix, f"{cfg.label} framebuffer")
        resolve = _per_pixel(cost.get("resolve_target_bytes", 0), n_pix, f"{cfg.label} resolve")
        per["resolve"] = resolve
        per["total"] = fb + resolve
        at = {}
        for w, h in resolutions:
            fb_b, tot_b = fb * w * h, (fb + resolve) * w * h
            at[f"{w}x{h}"] = {
                "framebuffer_bytes": fb_b,
                "total_bytes": tot_b,
                "framebuffer_MB": fb_b / 1e6,
                "total_MB": tot_b / 1e6,
                "framebuffer_MiB": fb_b / 2**20,
                "total_MiB": tot_b / 2**20,
            }
        rows.append(
            {
                "label": cfg.label,
                "technique": cfg.technique,
                "params": result.params,
                "bytes_per_pixel": per,
                "framebuffer_bytes_per_pixel": fb,
                "at": at,
            }
        )
    return rows


def _within(computed: float, quoted: float, decimals: int) -> bool:
    """``computed`` rounds to ``quoted`` at the source's precision (half a unit either way)."""
    return abs(computed - quoted) <= 0.5 * 10.0**-decimals + 1e-12


def compare_quoted(rows: list[dict], quotes=QUOTED) -> list[dict]:
    """Set every quoted figure against the computed one (``rows`` from :func:`memory_table`).

    Byte figures are compared in MB (1e6 bytes) and MiB, both with and without the 1x
    resolve target (the source does not say which); ``reproduced`` is true when any of them
    rounds to the quoted value. Ratios use the total bytes (a resolve target included where
    the technique has one: ACAA accumulates into the displayed target and needs none).
    """
    by_label = {r["label"]: r for r in rows}
    out = []
    for q in quotes:
        a = by_label.get(q.a)
        b = by_label.get(q.b) if q.b else None
        rec = {
            "key": q.key,
            "text": q.text,
            "source": q.source,
            "kind": q.kind,
            "quoted": q.value,
            "computed_from": [q.a] + ([q.b] if q.b else []),
            "note": q.note,
        }
        if a is None or (q.b and b is None):
            rec.update(computed=None, reproduced=False, note="configuration not in the table")
            out.append(rec)
            continue
        if q.kind == "bytes":
            at = a["at"][f"{q.resolution[0]}x{q.resolution[1]}"]
            candidates = {
                k: at[k] for k in ("total_MB", "framebuffer_MB", "total_MiB", "framebuffer_MiB")
            }
            rec["resolution"] = list(q.resolution)
            rec["computed"] = candidates
            rec["reproduced"] = any(_within(v, q.value, q.decimals) for v in candidates.values())
        else:
            ta, tb = a["bytes_per_pixel"]["total"], b["bytes_per_pixel"]["total"]
            value = 1.0 - ta / tb if q.key.startswith("agaa") else ta / tb
            rec["computed"] = value
            rec["reproduced"] = _within(value, q.value, q.decimals)
            if q.from_quotes:
                qa, qb = (next(x for x in quotes if x.key == k).value for k in q.from_quotes)
                rec["from_quotes"] = 1.0 - qa / qb
                rec["consistent_with_quotes"] = _within(1.0 - qa / qb, q.value, q.decimals)
        out.append(rec)
    return out


def aggregate_layout_bound(
    one_mb: float = 41.0,
    two_mb: float = 71.0,
    *,
    resolution=(1280, 736),
    samples: int = 8,
    depth_bytes: int = 4,
) -> dict:
    """What a layout ``base + K x aggregate`` would need to give the two quoted AGAA figures.

    With ``M1 = base + A`` and ``M2 = base + 2 A``: ``A = M2 - M1`` and ``base = 2 M1 - M2``.
    The base holds at least the N-sample depth buffer, ``N x depth_bytes`` per pixel; every
    figure is given in MB of 1e6 and of 2^20 bytes, and with the quoted values' rounding
    (+-0.5 MB) the largest possible base is ``2 (M1 + 0.5) - (M2 - 0.5)``.
    """
    w, h = resolution
    n_pix = w * h
    out = {"resolution": [w, h], "depth_buffer_MB": samples * depth_bytes * n_pix / 1e6}
    for unit, scale in (("MB", 1e6), ("MiB", 2**20)):
        base = 2 * one_mb - two_mb
        base_max = 2 * (one_mb + 0.5) - (two_mb - 0.5)
        out[unit] = {
            "aggregate_bytes_per_pixel": (two_mb - one_mb) * scale / n_pix,
            "base_bytes_per_pixel": base * scale / n_pix,
            "base_bytes_per_pixel_max": base_max * scale / n_pix,
            "depth_bytes_per_pixel": samples * depth_bytes,
            "feasible": base_max * scale / n_pix >= samples * depth_bytes,
        }
    return out


#: The slides' AGAA figures (MB at 1280x736) by aggregate count.
_SLIDES_AGAA_MB = {1: 41.0, 2: 71.0}


def agaa_breakdown(rows: list[dict], *, resolution=(1280, 736), samples: int = 8) -> list[dict]:
    """Why the model's AGAA differs from the slides' 41 / 71 MB: each buffer of the model's
    ``AGAA {samples}x, K aggregate(s)`` rows in MB at ``resolution``, the quoted figure, and
    the model without its per-sample normal buffer (the slides' Z-prepass keeps depth only).
    """
    w, h = resolution
    n_pix = w * h
    by_label = {r["label"]: r for r in rows}
    out = []
    for k, quoted in _SLIDES_AGAA_MB.items():
        row = by_label.get(f"AGAA {samples}x, {k} aggregate" + ("s" if k > 1 else ""))
        if row is None:
            continue
        per = row["bytes_per_pixel"]
        mb = {name: b * n_pix / 1e6 for name, b in per.items()}
        z_only = per["total"] - per.get("normal", 0)
        out.append(
            {
                "aggregates": k,
                "quoted_MB": quoted,
                "buffers_MB": mb,
                "framebuffer_MB": (per["total"] - per["resolve"]) * n_pix / 1e6,
                "z_prepass_only_total_MB": z_only * n_pix / 1e6,
                "z_prepass_only_total_MiB": z_only * n_pix / 2**20,
                "not_in_slides": "per-sample normal buffer (slides: per-sample visibility via "
                "Z-prepass)",
            }
        )
    return out


def memory_report(configs=DEFAULT_CONFIGS, *, resolutions=MEMORY_RESOLUTIONS) -> dict:
    """The JSON record of the memory section: table, quoted vs computed, layout bound."""
    rows = memory_table(configs, resolutions=resolutions)
    return {
        "schema": "raster-oracle.aa-memory/1",
        "resolutions": [list(r) for r in resolutions],
        "formats": "RGBA8 colour + D32 (float) depth where the model has the choice; AGAA "
        "normals and aggregates in the model's default formats; deferred MSAA: 16-byte "
        "G-buffer per sample (its colour column holds the albedo and material targets)",
        "rows": rows,
        "quoted": compare_quoted(rows),
        "layout_bound": aggregate_layout_bound(),
        "agaa_vs_slides": agaa_breakdown(rows),
        "probe": {"scene": _PROBE_SCENE, "size": list(_PROBE_SIZE)},
    }


def write_memory_report(out, data: dict | None = None) -> dict:
    """Write ``out/aa_memory.json`` and ``out/aa_memory.html`` (atomically); returns the data
    (``data``, or a fresh :func:`memory_report`)."""
    data = memory_report() if data is None else data
    section = aa_memory_section(data)
    title = "raster-oracle anti-aliasing memory"
    write_study(out, name="aa_memory", data=data, section=section, title=title)
    return data


def summary_lines(data: dict) -> list[str]:
    """The table at the first two resolutions and each quote's verdict, as text lines."""
    (w0, h0), (w1, h1) = data["resolutions"][:2]
    lines = [f"{'configuration':32s} {'B/px':>5s} {f'{w0}x{h0} MB':>14s} {f'{w1}x{h1} MB':>14s}"]
    for row in data["rows"]:
        per = row["bytes_per_pixel"]["total"]
        a, b = row["at"][f"{w0}x{h0}"]["total_MB"], row["at"][f"{w1}x{h1}"]["total_MB"]
        lines.append(f"{row['label']:32s} {per:5d} {a:14.1f} {b:14.1f}")
    for q in data["quoted"]:
        verdict = "reproduced" if q["reproduced"] else "not reproduced"
        c = q.get("computed")
        got = f"{c:.3f}" if isinstance(c, float) else f"{c['total_MB']:.1f} MB" if c else "-"
        lines.append(f"quoted: {q['text']}: {verdict} (computed {got})")
    for b in data.get("agaa_vs_slides", []):
        lines.append(
            f"AGAA K={b['aggregates']}: model {b['framebuffer_MB']:.1f} MB without the resolve "
            f"target, {b['buffers_MB'].get('normal', 0):.1f} MB of it per-sample normals; "
            f"Z-prepass only {b['z_prepass_only_total_MB']:.1f} MB with the resolve target, "
            f"slides {b['quoted_MB']:g} MB"
        )
    return lines
