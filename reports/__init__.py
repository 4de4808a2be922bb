"""HTML error reports of rendering techniques scored against a ray-traced reference.

Data in, files out: the package takes arrays and plain records, never renders and never
imports Mitsuba, Dr.Jit or :mod:`oracle`. One JSON-serialisable report dict feeds every
output (the HTML page and the JSON file beside it)::

    case = make_case(name="pcf 2048", scene="sponza", reference=ref, candidate=img,
                     kind="visibility", metrics={"misclassified": 0.013},
                     error_maps={"visibility_error": {"data": img - ref, "style": "signed"}},
                     thresholds={"misclassified": 0.02}, cost={"memory_bytes": 16777216},
                     technique="pcf", params={"resolution": 2048})
    report = build_report([case, ...], title="Shadow maps on sponza", provenance={...})
    write_report(report, out / "report.html")   # also writes out / "report.json"

To combine score folders, read their cases back with :func:`read_cases` and pass them all to
:func:`build_report`.

Other pages follow the same rule (a JSON-safe record, rendered by a jinja2 template of
``templates/`` with autoescape on and formatting in the Python filters of
:mod:`reports.formatting`, :mod:`reports.svg`; plots drawn by matplotlib in
:mod:`reports.plots`):

- :mod:`reports.sweep`: the sweep report (a summary at the top,
  :mod:`reports.sections.overview`; Pareto fronts, sensitivity, best at equal cost, every
  case), ``templates/sweep.html``, with study sections after the fronts;
- :mod:`reports.sections`: the studies' section records (claims, extremes, converge,
  anti-aliasing memory: ``claims_section(data)``, ...), each shown by
  ``templates/section_<kind>.html``, on a study's own page (:func:`~reports.sections.study_page`,
  :func:`~reports.sections.render_study_page`) or inside the sweep report, whose JSON holds
  them under ``"sections"``.

Case record (``make_case``)
---------------------------
``schema``
    ``"raster-oracle.report-case/1"``.
``name``, ``scene``, ``kind``, ``technique``, ``family``
    Strings (``technique``/``family`` may be ``None``; ``family`` defaults to ``technique``).
    ``kind`` is ``"visibility"`` or ``"color"``.
``params``
    Technique parameters, JSON values.
``width``, ``height``
    Image size in pixels.
``thumbnail``
    ``{"factor", "width", "height"}``: the embedded images are the full image reduced by the
    integer ``factor`` (1 up to ``max_size``, default 960 px on the longer side).
``metrics``
    ``name -> float``; non-finite values are the strings ``"nan"``, ``"inf"``, ``"-inf"``.
``thresholds``
    ``name -> {"max": float}`` and/or ``{"min": float}``; a bare number given to
    ``make_case`` is a ``"max"``.
``noise_floor``
    ``name -> float``: the metric between two independent references.
``cost``
    ``name -> number`` (``memory_bytes``, ``texels_rendered``, ...) or ``None``.
``failing``
    Names of the metrics outside their thresholds (NaN fails).
``within_noise``
    Names of the metrics no worse than their noise floor, in each metric's direction
    (``make_case(directions=...)``: at or below it for lower-is-better metrics, the default;
    at or above it for higher-is-better ones such as SSIM and PSNR).
``directions``
    ``name -> "lower" | "higher" | "zero" | "info"``: which way each metric is better, as
    given to ``make_case`` (absent from reports written before it).
``status``
    ``"pass"``, ``"fail"``, or ``"unchecked"`` (no thresholds and no checks). A failed
    check fails the case.
``checks``
    The run's judged gates and baseline comparisons (``make_case(checks=...)``): ``{"name",
    "kind", "metric", "passed", "line", "value", "limit", "noise_floor", "previous",
    "previous_noise_floor"}``; empty when none was given.
``diagnoses``
    Likely causes of a large error (strings), shown on the first screen; may be empty.
``images``
    ``{"reference": uri, "candidate": uri}``: ``data:`` URIs (PNG for visibility, WebP or
    JPEG for colour).
``error_maps``
    List of ``{"name", "style" ("signed" | "magma"), "range": [lo, hi], "primary": bool,
    "image": PNG data URI (fixed range; signed: green = positive = false-lit, red = negative =
    false-shadowed, black = 0), "histogram": {"edges": [n + 1], "counts": [n], "total",
    "below", "above"}, "summary": {"mean", "mean_abs", "p99_abs", "max_abs",
    "nonzero_fraction"}}``. ``sum(counts) == total == width * height``; values outside
    the range are counted in the end bins and in ``below``/``above``.
``worst_tiles``
    ``{"map": primary map name, "tile_size": px, "tiles": [{"rank", "x", "y", "w", "h"
    (pixel rectangle, row 0 at the top), "mean_abs_error", "reference", "candidate",
    "error" (full-resolution PNG data URIs of that rectangle)}]}``, worst first.
``exr_links``
    List of ``{"label", "path" (as given, relative to the report's folder), "href"
    (URL-quoted path)}``.
``viewer``
    ``None``, or the linear float images (every frame) of the page's pixel viewer: a record
    of :func:`reports.viewer.viewer_record` (keys in the :mod:`reports.viewer` docstring).
    Records written before it existed lack the key; they read back as ``None``.

Report record (``build_report``)
--------------------------------
``schema``
    ``"raster-oracle.report/1"``.
``title``, ``provenance``
    The page title and the provenance record (JSON values; nested dicts allowed).
``metric_names``, ``cost_names``
    Column order of the summary table: every metric and cost key, first seen first.
``directions``
    ``metric -> "lower" | "higher" | "zero" | "info"`` (the first case's that gives one;
    default ``"lower"``): which way each column is better.
``summary``
    ``{"n_cases", "n_pass", "n_fail", "n_unchecked", "thresholds": name -> bounds or
    "varies", "noise_floor": name -> float or "varies", "failed_checks": [every failed
    check of every case, with "case_id", "case" and "scene"], "n_checks"}``.
``tradeoff``
    ``None`` when no case has a cost, else ``{"cost_key", "metric", "families": [{"family",
    "points": [{"case_id", "name", "technique", "params", "cost", "error", "on_front"}],
    "front": [indices into points, by increasing cost]}]}``.
``colorbars``
    ``style -> PNG data URI`` of each palette used (256 x 1, low end left).
``cases``
    The case records, each with an added ``"id"`` (``"case-1"``, ...).
"""

from ._build import REPORT_SCHEMA, build_report, read_cases
from ._case import CASE_SCHEMA, make_case
from ._tradeoff import pareto_front
from ._write import render_html, write_report
from .images import colorize
from .viewer import viewer_record

__all__ = [
    "CASE_SCHEMA",
    "REPORT_SCHEMA",
    "build_report",
    "colorize",
    "make_case",
    "pareto_front",
    "read_cases",
    "render_html",
    "viewer_record",
    "write_report",
]
