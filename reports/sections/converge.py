"""The oracle-convergence section: a log-log plot of true error and reported standard error
against samples per pixel, and the tables behind it.

Data in (the record of :func:`oracle.studies.converge.run_converge`), section record out;
``templates/section_converge.html`` renders it.
"""

from __future__ import annotations

from collections.abc import Mapping

from ._record import section_record

__all__ = ["converge_section", "fmt_slope"]


def _series(data: Mapping) -> list[dict]:
    """The plotted lines: true and reported error of the ladder, adaptive, the fit."""
    ladder = data["ladder"]
    spp = [r["spp"] for r in ladder]
    vis = [r["visibility"] for r in ladder]
    series = [
        {"name": "visibility true RMS", "x": spp, "y": [v["rms"] for v in vis]},
        {
            "name": "visibility stderr RMS",
            "x": spp,
            "y": [v["stderr_rms"] for v in vis],
            "dashed": True,
        },
        {"name": "visibility true max", "x": spp, "y": [v["max"] for v in vis]},
        {"name": "coverage true RMS", "x": spp, "y": [r["coverage"]["rms"] for r in ladder]},
    ]
    for c, short in (("soft_visibility", "soft vis"), ("light_fraction", "light fraction")):
        if c in ladder[0]:  # an area light's soft channels
            series.append(
                {"name": f"{short} true RMS", "x": spp, "y": [r[c]["rms"] for r in ladder]}
            )
    adaptive = data.get("adaptive")
    if adaptive:
        series.append(
            {
                "name": "adaptive vis RMS",
                "x": [adaptive["mean_spp"]],
                "y": [adaptive["visibility"]["rms"]],
            }
        )
    fit = data["fit"]["visibility"]["true_rms"]
    if fit.get("slope") is not None:
        series.append(
            {
                "name": f"fit spp^{fit['slope']:.2f}",
                "x": spp,
                "y": [fit["a"] * s ** fit["slope"] for s in spp],
                "dashed": True,
            }
        )
    return series


def _rows(data: Mapping) -> list[dict]:
    """The ladder table: one row per spp, then adaptive sampling."""
    keys = ("visibility", "coverage", "rays", "seconds")
    keys += tuple(c for c in ("soft_visibility", "light_fraction") if c in data["ladder"][0])
    rows = [{"label": str(r["spp"]), **{k: r[k] for k in keys}} for r in data["ladder"]]
    adaptive = data.get("adaptive")
    if adaptive:
        label = f"adaptive ({adaptive['mean_spp']:.1f} mean)"
        rows.append({"label": label, **{k: adaptive[k] for k in keys}})
    return rows


def converge_section(
    data: Mapping, *, section_id: str = "converge", title: str | None = None
) -> dict:
    """The section record of a convergence run: the data, the plotted ``series`` and the
    ladder table's ``rows`` (default title: "Oracle convergence on SCENE")."""
    if title is None:
        title = f"Oracle convergence on {data['scene'].get('name', '?')}"
    return section_record(
        "converge",
        section_id=section_id,
        title=title,
        data=data,
        series=_series(data),
        rows=_rows(data),
    )


def fmt_slope(fit: Mapping | None) -> str:
    """The slope of a power-law fit to three decimals; — when there was none."""
    if not fit or fit.get("slope") is None:
        return "—"
    return f"{fit['slope']:.3f}"
