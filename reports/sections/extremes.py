"""The numerical-extremes section: a matrix of models x extremes.

Data in (the dict of :func:`oracle.studies.extremes.run.run_extremes`), HTML out. A cell shows the
model's error against the oracle (or n/a, refused, non-finite, error), green when the
measured outcome matches the documented expectation and red when it does not; the
expectation and its reason are in the cell's tooltip and in the list below the matrix.
Every piece of text from the data is escaped here.
"""

from __future__ import annotations

from collections.abc import Mapping

from markupsafe import escape

from .._format import fmt_number
from .converge import STYLES, page

__all__ = ["render_extremes", "render_extremes_page"]


def _cell_text(c: Mapping) -> str:
    status = c.get("status")
    if status == "ok":
        return fmt_number(c.get("error"))
    return str(status)


def _short(c: Mapping) -> str:
    """The expected band under the value (not for n/a cells)."""
    if c.get("status") == "n/a" or not c.get("expected_short"):
        return ""
    return f'<br><small style="color:#64748b">{escape(c["expected_short"])}</small>'


def render_extremes(data: Mapping) -> str:
    """HTML fragment: the matrix, then each extreme's description and each non-default
    expectation with its reason."""
    techs = list(data.get("techniques", []))
    cells = {(c["extreme"], c["technique"]): c for c in data.get("cells", [])}
    extremes = list(data.get("extremes", {}))
    res = data.get("resolution", ["?", "?"])
    bases = ", ".join(
        f"{scene} for {fam}"
        for fam, scene in (data.get("base_scenes") or {"": data.get("base_scene", "")}).items()
    )
    out = [
        "<h2>Numerical extremes</h2>",
        f"<p>Every model x every extreme (base scenes: {escape(bases)}) "
        f"at {escape(str(res[0]))}x{escape(str(res[1]))} px against a "
        f"{escape(str(data.get('reference_spp', '')))}-spp oracle; maps at most "
        f"{escape(str(data.get('cell_map', '')))}^2 (huge: "
        f"{escape(str(data.get('huge_map', '')))}^2). A cell is the error (misclassified "
        "receivers; coverage RMSE for anti-aliasing models) over its expected band; green: as "
        "documented, red: not. Hover a cell for the reason.</p>",
    ]
    unexpected = data.get("unexpected") or []
    if unexpected:
        out.append(f"<p class=bad>Not as documented: {escape(', '.join(map(str, unexpected)))}</p>")
    out.append("<table><tr><th class=l>extreme</th>")
    out.extend(f"<th>{escape(t)}</th>" for t in techs)
    out.append("</tr>")
    for ext in extremes:
        out.append(f"<tr><td class=l>{escape(ext)}</td>")
        for t in techs:
            c = cells.get((ext, t))
            if c is None:
                out.append("<td class=na>—</td>")
                continue
            css = "na" if c.get("status") == "n/a" else ("ok" if c.get("outcome_met") else "bad")
            tip = f"expected: {c.get('expected')}; {c.get('reason') or ''}"
            if c.get("message"):
                tip += f"; {c['message']}"
            out.append(
                f'<td class="{css}" style="{STYLES[css]}" title="{escape(tip)}">'
                f"{escape(_cell_text(c))}{_short(c)}</td>"
            )
        out.append("</tr>")
    out.append("</table><h3>Extremes</h3><ul>")
    for ext, info in data.get("extremes", {}).items():
        out.append(f"<li><b>{escape(ext)}</b>: {escape(info.get('description', ''))}</li>")
    out.append("</ul><h3>Documented outcomes</h3><ul>")
    seen = set()
    for c in data.get("cells", []):
        key = (c.get("expected"), c.get("reason"))
        if c.get("status") == "n/a" or key in seen:
            continue
        seen.add(key)
        who = sorted(
            f"{d['technique']} x {d['extreme']}"
            for d in data["cells"]
            if (d.get("expected"), d.get("reason")) == key and d.get("status") != "n/a"
        )
        label = ", ".join(who) if len(who) <= 6 else f"{len(who)} cells"
        out.append(
            f"<li><b>{escape(str(c.get('expected')))}</b> ({escape(label)}): "
            f"{escape(c.get('reason') or '')}</li>"
        )
    out.append("</ul>")
    return "\n".join(out)


def render_extremes_page(data: Mapping) -> str:
    """``extremes.html``: the fragment of :func:`render_extremes` as a page."""
    return page("raster-oracle extremes", render_extremes(data))
