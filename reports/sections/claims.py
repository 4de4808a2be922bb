"""The claims section: each headline claim of the seeds, its source, the measured value with
error bars and the verdict.

Data in (the dict of :func:`oracle.studies.claims.run.run_claims`), HTML out; every piece of
text from the data is escaped here.
"""

from __future__ import annotations

import json
from collections.abc import Mapping

from markupsafe import escape

from .._format import fmt_number
from .converge import STYLES, page

__all__ = ["fmt_summary", "render_claims", "render_claims_page"]

_VERDICT_CSS = {"reproduced": "ok", "partly": "part", "not reproduced": "bad"}


def fmt_summary(value) -> str:
    """``mean ± stderr (n, min..max)`` of a :func:`oracle.studies.claims.run.summary` record."""
    if not isinstance(value, Mapping) or value.get("mean") is None:
        return "—"
    text = f"{fmt_number(value['mean'])} ± {fmt_number(value.get('stderr'))}"
    if value.get("n", 0) > 1:
        text += (
            f" (n = {value['n']}, {fmt_number(value.get('min'))} .. {fmt_number(value.get('max'))})"
        )
    return text


def _extra(extra) -> str:
    if not isinstance(extra, Mapping) or not extra:
        return ""
    items = []
    for k, v in extra.items():
        if isinstance(v, Mapping) and "mean" in v:
            text = fmt_summary(v)
        elif isinstance(v, float | int) and not isinstance(v, bool):
            text = fmt_number(v)
        else:
            text = json.dumps(v, default=str)
        items.append(f"<li>{escape(str(k))}: {escape(text)}</li>")
    return "<ul>" + "".join(items) + "</ul>"


def render_claims(data: Mapping) -> str:
    """HTML fragment: one row per claim, with the cases in a collapsed block."""
    res = data.get("resolution", ["?", "?"])
    counts = data.get("counts", {})
    out = [
        "<h2>Claims of the seed documents</h2>",
        f"<p>Measured at {escape(str(res[0]))}x{escape(str(res[1]))} px against a "
        f"{escape(str(data.get('reference_spp', '')))}-spp oracle. Values are mean ± standard "
        "error over the cases (scenes, frames or frame pairs) with their count and range. "
        + str(escape(", ".join(f"{k}: {v}" for k, v in counts.items())))
        + "</p>",
        "<table><tr><th class=l>claim</th><th class=l>source</th><th class=l>measured</th>"
        "<th>verdict</th><th class=l>rule</th></tr>",
    ]
    for row in data.get("claims", []):
        verdict = str(row.get("verdict", ""))
        css = _VERDICT_CSS.get(verdict, "na")
        if row.get("note"):
            measured = f"<span class=na>{escape(row['note'])}</span>"
        else:
            measured = (
                f"{escape(row.get('value_text', ''))}: <b>{escape(fmt_summary(row.get('value')))}"
                f"</b>{_extra(row.get('extra'))}"
            )
            cases = row.get("cases") or []
            if cases:
                measured += (
                    f"<details><summary>{len(cases)} cases</summary><pre>"
                    f"{escape(json.dumps(cases, indent=1, default=str))}</pre></details>"
                )
        out.append(
            f"<tr><td class=l><b>{escape(str(row.get('id', '')))}</b><br>"
            f"<q>{escape(str(row.get('claim', '')))}</q></td>"
            f"<td class=l>{escape(str(row.get('source', '')))}</td>"
            f"<td class=l>{measured}</td>"
            f'<td class="{css}" style="{STYLES[css]}">{escape(verdict)}</td>'
            f"<td class=l>{escape(str(row.get('rule', '')))}</td></tr>"
        )
    out.append("</table>")
    return "\n".join(out)


def render_claims_page(data: Mapping) -> str:
    """``claims.html``: the fragment of :func:`render_claims` as a page."""
    return page("raster-oracle claims", render_claims(data))
