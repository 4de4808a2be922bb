"""The oracle-convergence section: a log-log plot of true error and reported standard error
against samples per pixel, and the table behind it.

Data in (the dict of :func:`oracle.studies.converge.run_converge`), HTML out; every piece of text
taken from the data is escaped here.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

from markupsafe import Markup, escape

from .._format import fmt_number

__all__ = ["STYLES", "loglog_svg", "page", "render_converge", "render_converge_page"]

_FONT = 'font-family="system-ui, sans-serif" font-size="11"'
_COLOURS = ("#2563eb", "#dc2626", "#16a34a", "#9333ea", "#ea580c", "#0891b2")
#: Inline cell styles (the fragments keep their colours inside another page's CSS).
STYLES = {
    "ok": "background:#dcfce7",
    "bad": "background:#fee2e2",
    "part": "background:#fef9c3",
    "na": "color:#64748b",
}
_CSS = """body{font-family:system-ui,sans-serif;margin:2em;color:#0f172a;max-width:1100px}
table{border-collapse:collapse;font-size:13px;margin:1em 0}
td,th{border:1px solid #e2e8f0;padding:3px 8px;text-align:right;white-space:nowrap}
th{background:#f1f5f9}td.l,th.l{text-align:left;white-space:normal}
.ok{background:#dcfce7}.bad{background:#fee2e2}.part{background:#fef9c3}.na{color:#64748b}
svg{max-width:640px;display:block}"""


def _decades(lo: float, hi: float) -> tuple[int, int]:
    a = math.floor(math.log10(lo) + 1e-9)
    b = math.ceil(math.log10(hi) - 1e-9)
    return a, b if b > a else a + 1


def loglog_svg(series: Sequence[Mapping], *, x_label: str, y_label: str, title: str = "") -> Markup:
    """A log-log line plot. ``series``: ``{"name", "x", "y", "dashed"?}`` (positive values
    only are drawn; others are left out)."""
    width, height = 560.0, 330.0
    left, right, top, bottom = 64.0, 150.0, 20.0, 40.0
    pw, ph = width - left - right, height - top - bottom
    xs = [float(v) for s in series for v in s["x"] if v and v > 0]
    ys = [float(v) for s in series for v in s["y"] if v is not None and v > 0]
    if not xs or not ys:
        return Markup('<p class="na">nothing to plot (no positive values)</p>')
    x0, x1 = _decades(min(xs), max(xs))
    y0, y1 = _decades(min(ys), max(ys))

    def sx(v: float) -> float:
        return left + pw * (math.log10(v) - x0) / (x1 - x0)

    def sy(v: float) -> float:
        return top + ph * (1.0 - (math.log10(v) - y0) / (y1 - y0))

    parts = [
        f'<svg viewBox="0 0 {width:g} {height:g}" role="img" aria-label="{escape(title)}" '
        'xmlns="http://www.w3.org/2000/svg">',
        f'<rect x="{left:g}" y="{top:g}" width="{pw:g}" height="{ph:g}" fill="#f8fafc" '
        'stroke="#cbd5e1"/>',
    ]
    for e in range(x0, x1 + 1):
        x = sx(10.0**e)
        parts.append(
            f'<line x1="{x:.1f}" x2="{x:.1f}" y1="{top:g}" y2="{top + ph:g}" stroke="#e2e8f0"/>'
            f'<text x="{x:.1f}" y="{top + ph + 14:g}" text-anchor="middle" fill="#475569" '
            f"{_FONT}>1e{e}</text>"
        )
    for e in range(y0, y1 + 1):
        y = sy(10.0**e)
        parts.append(
            f'<line x1="{left:g}" x2="{left + pw:g}" y1="{y:.1f}" y2="{y:.1f}" stroke="#e2e8f0"/>'
            f'<text x="{left - 6:g}" y="{y + 3:.1f}" text-anchor="end" fill="#475569" '
            f"{_FONT}>1e{e}</text>"
        )
    drawn = 0
    for k, s in enumerate(series):
        colour = _COLOURS[k % len(_COLOURS)]
        pts = [
            (sx(float(x)), sy(float(y)))
            for x, y in zip(s["x"], s["y"], strict=True)
            if x and x > 0 and y is not None and y > 0
        ]
        if not pts:
            continue
        dash = ' stroke-dasharray="5 3"' if s.get("dashed") else ""
        d = "M" + "L".join(f"{x:.1f},{y:.1f}" for x, y in pts)
        parts.append(f'<path d="{d}" fill="none" stroke="{colour}" stroke-width="1.6"{dash}/>')
        for x, y in pts:
            parts.append(f'<circle cx="{x:.1f}" cy="{y:.1f}" r="2.5" fill="{colour}"/>')
        ly = top + 14 + 16 * drawn
        drawn += 1
        parts.append(
            f'<line x1="{left + pw + 10:g}" x2="{left + pw + 30:g}" y1="{ly - 4:g}" '
            f'y2="{ly - 4:g}" stroke="{colour}" stroke-width="2"{dash}/>'
            f'<text x="{left + pw + 34:g}" y="{ly:g}" fill="#0f172a" {_FONT}>'
            f"{escape(s['name'])}</text>"
        )
    parts.append(
        f'<text x="{left + pw / 2:g}" y="{height - 8:g}" text-anchor="middle" fill="#0f172a" '
        f"{_FONT}>{escape(x_label)} (log)</text>"
        f'<text transform="translate(14 {top + ph / 2:g}) rotate(-90)" text-anchor="middle" '
        f'fill="#0f172a" {_FONT}>{escape(y_label)} (log)</text></svg>'
    )
    return Markup("".join(parts))


def _slope(fit: Mapping | None) -> str:
    if not fit or fit.get("slope") is None:
        return "—"
    return f"{fit['slope']:.3f}"


def render_converge(data: Mapping) -> str:
    """HTML fragment: plot, fit, targets and the ladder table."""
    ladder = data["ladder"]
    spp = [r["spp"] for r in ladder]
    series = [
        {"name": "visibility true RMS", "x": spp, "y": [r["visibility"]["rms"] for r in ladder]},
        {
            "name": "visibility stderr RMS",
            "x": spp,
            "y": [r["visibility"]["stderr_rms"] for r in ladder],
            "dashed": True,
        },
        {"name": "visibility true max", "x": spp, "y": [r["visibility"]["max"] for r in ladder]},
        {"name": "coverage true RMS", "x": spp, "y": [r["coverage"]["rms"] for r in ladder]},
    ]
    if data.get("adaptive"):
        a = data["adaptive"]
        series.append(
            {"name": "adaptive vis RMS", "x": [a["mean_spp"]], "y": [a["visibility"]["rms"]]}
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
    scene = data["scene"]
    title = f"Oracle convergence on {scene.get('name', '?')}"
    out = [
        f"<h2>{escape(title)}</h2>",
        f"<p>{escape(str(data['resolution'][0]))}x{escape(str(data['resolution'][1]))} px; "
        f"truth {escape(str(data['truth']['spp']))} spp (seed {escape(str(data['truth']['seed']))}"
        f", mean visibility stderr {escape(fmt_number(data['truth']['visibility_stderr_mean']))}"
        ").</p>",
        str(loglog_svg(series, x_label="samples per pixel", y_label="error", title=title)),
        "<table><tr><th class=l>fit (least squares, log-log)</th><th>visibility</th>"
        "<th>coverage</th><th>expected</th></tr>",
    ]
    exp = data.get("expected_slope", {})
    for key, label in (
        ("true_rms", "slope of true RMS error"),
        ("reported_stderr_rms", "slope of reported stderr RMS"),
    ):
        out.append(
            f"<tr><td class=l>{escape(label)}</td>"
            f"<td>{escape(_slope(data['fit']['visibility'][key]))}</td>"
            f"<td>{escape(_slope(data['fit']['coverage'][key]))}</td>"
            f"<td>{escape(fmt_number(exp.get(key)))}</td></tr>"
        )
    out.append("</table>")
    if exp.get("why"):
        out.append(f"<p>{escape(exp['why'])}.</p>")
    out.append("<table><tr><th>target RMS</th><th>spp (measured)</th><th>spp (fit)</th></tr>")
    for t in data["targets"]:
        out.append(
            f"<tr><td>{escape(fmt_number(t['target_rms']))}</td>"
            f"<td>{escape(fmt_number(t['spp_measured']))}</td>"
            f"<td>{escape(fmt_number(t['spp_fitted']))}</td></tr>"
        )
    out.append("</table>")
    head = (
        "<tr><th>spp</th><th>vis RMS</th><th>vis max</th><th>vis stderr mean</th>"
        "<th>vis stderr RMS</th><th>beyond 3 stderr</th><th>cov RMS</th><th>cov max</th>"
        "<th>rays</th><th>seconds</th></tr>"
    )
    rows = [dict(r, label=str(r["spp"])) for r in ladder]
    if data.get("adaptive"):
        a = data["adaptive"]
        rows.append(dict(a, label=f"adaptive ({a['mean_spp']:.1f} mean)"))
    a = data.get("adaptive") or {}
    if a.get("uniform_spp_same_rms_fit") is not None:
        out.append(
            f"<p>Adaptive sampling (target stderr {escape(fmt_number(a['target_stderr']))}): "
            f"{escape(fmt_number(a['mean_spp']))} samples per pixel on average reach the true "
            f"RMS error that uniform sampling reaches at "
            f"{escape(fmt_number(a['uniform_spp_same_rms_fit']))} spp (on the fit): "
            f"{escape(fmt_number(a['uniform_over_adaptive_samples']))}x fewer samples.</p>"
        )
    out.append("<table>" + head)
    for r in rows:
        v, c = r["visibility"], r["coverage"]
        cells = [
            r["label"],
            fmt_number(v["rms"]),
            fmt_number(v["max"]),
            fmt_number(v["stderr_mean"]),
            fmt_number(v["stderr_rms"]),
            fmt_number(v["beyond_3_stderr"]),
            fmt_number(c["rms"]),
            fmt_number(c["max"]),
            fmt_number(int(r["rays"])),
            fmt_number(r["seconds"]),
        ]
        out.append("<tr>" + "".join(f"<td>{escape(x)}</td>" for x in cells) + "</tr>")
    out.append("</table>")
    return "\n".join(out)


def page(title: str, body: str) -> str:
    """A self-contained HTML page around an (already escaped) body fragment."""
    return (
        '<!doctype html><html lang="en"><head><meta charset="utf-8">'
        f"<title>{escape(title)}</title><style>{_CSS}</style></head><body>{body}</body></html>"
    )


def render_converge_page(data: Mapping) -> str:
    """``converge.html``: the fragment of :func:`render_converge` as a page."""
    return page(f"raster-oracle converge {data['scene'].get('name', '')}", render_converge(data))
