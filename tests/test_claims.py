"""Claims: sources quoted verbatim, verdict rules, measurements of the exact claims."""

from __future__ import annotations

import math
import re
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from raster_oracle.oracle.cli.app import main
from raster_oracle.oracle.studies.claims import run as C
from raster_oracle.reports.formatting import fmt_summary
from raster_oracle.reports.sections import claims_section, render_section

from raster_oracle import raster_models

#: Copies of the project's seed documents and TECHNIQUES.md (``../shared/`` is not part of a
#: clone, so CI could not read them there).
SEEDS = Path(__file__).resolve().parent / "data" / "seeds"
#: Film size of the measured claims in this module (the cheapest that still has shadows).
SIZE = (64, 36)


def _norm(text: str) -> str:
    return re.sub(r"[^a-z0-9%]+", " ", text.lower()).strip()


def test_summary_hand_computed():
    s = C.summary([1.0, 2.0, 3.0, 6.0])
    assert s["mean"] == 3.0 and s["n"] == 4 and (s["min"], s["max"]) == (1.0, 6.0)
    assert s["stderr"] == pytest.approx(math.sqrt(14.0 / 3.0) / 2.0)
    assert C.summary([5.0])["stderr"] == 0.0
    assert C.summary([])["mean"] is None
    assert fmt_summary(s).startswith("3 ± 1.08") and "n = 4" in fmt_summary(s)


def test_at_least_nine_claims_each_with_source_and_rule():
    assert len(C.CLAIMS) >= 9
    assert len({c.id for c in C.CLAIMS}) == len(C.CLAIMS)
    for c in C.CLAIMS:
        assert c.claim and c.rule and c.techniques
        assert "seed 00" in c.source or "Ritschel" in c.source or c.id in OTHER_QUOTES


#: Claims quoting neither a seed nor TECHNIQUES.md: their source and the exact quote.
OTHER_QUOTES = {
    "pcss-penumbra-error-grows": (
        "issue 38",
        "PCSS's penumbra width error grows with the blocker-receiver distance",
    ),
    "msm-bleeds-less": (
        "Peters and Klein, Moment Shadow Mapping, I3D 2015, abstract",
        "Like variance shadow mapping it allows for the application of all kinds of efficient "
        "texture filtering [...] However it is designed to provide a substantially higher "
        "quality.",
    ),
    "alpha-box-mips-lose-foliage": (
        "issue 44",
        "box-filtered mips lose more than 50% of the foliage beyond 5 m; coverage-preserving "
        "mips keep it",
    ),
    "alpha-threejs-a2c-shrinks": (
        "issue 44",
        "three.js alpha-to-coverage shrinks silhouettes by about half a pixel",
    ),
    "asvgf-less-lag": (
        "issue 46",
        "gradient-based history rejection reduces lag after a light change compared with SVGF",
    ),
}


def test_other_quotes_are_transcribed():
    for c in C.CLAIMS:
        if c.id in OTHER_QUOTES:
            source, quote = OTHER_QUOTES[c.id]
            assert c.source.startswith(source) and c.claim == quote


def test_quotes_are_in_the_seed_documents():
    """Every quoted fragment of a claim occurs, word for word, in the seed its source names
    (or, for the paper quoted in TECHNIQUES.md, there)."""
    seeds = {p.name[:3]: _norm(p.read_text("utf-8")) for p in SEEDS.glob("*.txt")}
    assert len(seeds) == 4
    techniques = _norm((SEEDS.parent / "TECHNIQUES.md").read_text("utf-8"))
    for c in C.CLAIMS:
        if c.id in OTHER_QUOTES:
            continue
        m = re.match(r"seed (00\d)", c.source)
        text = seeds[m.group(1)] if m else techniques
        # the quote's fragments between elisions and parenthesised glosses
        parts = re.split(r"\[\.\.\.\]|\(and .*?\)|\(paper .*?\)|; caveat: .*|;.*vs.*", c.claim)
        for part in parts:
            frag = _norm(part)
            if len(frag) > 12:
                assert frag in text, (c.id, frag)


def _fake(vis_by_technique):
    """A context whose models return fixed misclassified fractions."""

    class Ctx(C.ClaimContext):
        def scene(self, name, *, frame=0, path=None, size=None):
            return SimpleNamespace(name=name, frame=frame, width=4, height=4)

        def run(self, technique, loaded, **params):
            return SimpleNamespace(
                technique=technique,
                name=loaded.name,
                cost={"shadow_map_bytes": 100, "texels_rendered": 10},
            )

        def shadow_error(self, loaded, result):
            return {"misclassified_fraction": vis_by_technique[result.technique](loaded.name)}

    return Ctx(quick=True, shadow_scenes=("a", "b"), frames=4)


@pytest.mark.parametrize(
    ("sdsm", "csm", "verdict"),
    [
        (lambda s: 0.01, lambda s: 0.03, C.REPRODUCED),
        (lambda s: 0.01 if s == "a" else 0.05, lambda s: 0.06 if s == "a" else 0.04, C.PARTLY),
        (lambda s: 0.03, lambda s: 0.01, C.NOT),
        # worse by less than the tolerance in one case is "never worse"
        (lambda s: 0.011 if s == "a" else 0.01, lambda s: 0.01 if s == "a" else 0.05, C.REPRODUCED),
    ],
)
def test_sdsm_vs_pssm_rule(sdsm, csm, verdict):
    claim = next(c for c in C.CLAIMS if c.id == "sdsm-beats-pssm")
    out = claim.measure(_fake({"sdsm": sdsm, "csm": csm}))
    assert out["verdict"] == verdict
    assert out["value"]["n"] == 4  # 2 scenes x frames 0 and 2


def test_unavailable_technique_is_not_measured(monkeypatch):
    monkeypatch.delitem(raster_models.TECHNIQUES, "izb")
    data = C.run_claims(None, only=["izb-exact-32spp-under-2x"])
    (row,) = data["claims"]
    assert row["verdict"] == "not measured"
    assert row["note"] == "not measured: technique not available (izb)"
    assert data["counts"]["not measured"] == 1


@pytest.fixture(scope="module")
def measured(tmp_path_factory):
    out = tmp_path_factory.mktemp("claims")
    only = ["coherent-lossless", "izb-exact-32spp-under-2x", "acaa-equals-msaa"]
    return out, C.run_claims(out, only=only, size=SIZE)


def test_coherent_compression_is_lossless(measured):
    _, data = measured
    row = next(r for r in data["claims"] if r["id"] == "coherent-lossless")
    assert row["extra"]["lossless"] is True
    for case in row["cases"]:
        assert case["visibility_max_diff"] == 0.0 and case["decompressed_mismatches"] == 0
    assert row["value"]["min"] > 1.0
    assert row["verdict"] == C.REPRODUCED


def test_izb_one_sample_equals_the_centre_shadow_ray(measured):
    _, data = measured
    row = next(r for r in data["claims"] if r["id"] == "izb-exact-32spp-under-2x")
    assert row["extra"]["mismatches_1spp_vs_centre_ray"] == 0
    assert all(c["receivers"] > 100 for c in row["cases"])
    assert row["verdict"] in (C.REPRODUCED, C.PARTLY)  # exactness holds; the ratio is measured


def test_acaa_equals_msaa_except_ties(measured):
    _, data = measured
    row = next(r for r in data["claims"] if r["id"] == "acaa-equals-msaa")
    plain = [c for c in row["cases"] if not c["coplanar"]]
    ties = [c for c in row["cases"] if c["coplanar"]]
    assert plain and ties  # decal has ties
    assert max(c["color_rel_diff"] for c in plain) <= C.ACAA_EQUAL
    assert min(c["color_rel_diff"] for c in ties) > 0.05  # counted twice: much brighter
    # 8 samples: MSAA 8 x (4 colour + 4 depth) + 4 resolve = 68 B/px, ACAA 8 x 4 + 4 = 36
    for c in row["cases"]:
        assert c["memory_ratio_rgba8"] == pytest.approx(36 / 68)


def test_files_and_page(measured):
    out, data = measured
    assert (out / "claims.json").is_file() and (out / "claims.html").is_file()
    evil = dict(data, claims=[{**data["claims"][0], "claim": "<script>x</script>"}])
    html = render_section(claims_section(evil))
    assert "<script>x" not in html and "&lt;script&gt;" in html
    page = (out / "claims.html").read_text()
    for row in data["claims"]:
        assert f"<b>{row['id']}</b>" in page and f">{row['verdict']}</td>" in page
    assert np.isfinite(data["wall_seconds"])


def test_cli_unknown_claim(tmp_path, capsys):
    out = tmp_path / "never"
    assert main(["claims", "--only", "nope", "--out", str(out)]) == 2
    assert "unknown claim" in capsys.readouterr().err
    assert not out.exists()
