"""Report sections: each turns a study's JSON record into a JSON-safe section record
(``{"schema", "kind", "id", "title", "failed", "error", "data", ...view}``) that a template
(``templates/section_<kind>.html``) renders; :mod:`reports.sections.page` renders pages of
them. The sweep report's own page view is :mod:`reports.sections.sweep`."""

from ._record import SECTION_KINDS, SECTION_SCHEMA, failed_section
from .aa_memory import aa_memory_section
from .aa_ranking import aa_ranking_section
from .alpha_foliage import alpha_foliage_section
from .claims import claims_section
from .converge import converge_section
from .extremes import extremes_section
from .page import (
    STUDY_PAGE_SCHEMA,
    render_section,
    render_study_page,
    render_sweep_page,
    study_page,
)
from .soft_shadows import soft_shadows_section

__all__ = [
    "SECTION_KINDS",
    "SECTION_SCHEMA",
    "STUDY_PAGE_SCHEMA",
    "aa_memory_section",
    "aa_ranking_section",
    "alpha_foliage_section",
    "claims_section",
    "converge_section",
    "extremes_section",
    "failed_section",
    "render_section",
    "render_study_page",
    "render_sweep_page",
    "soft_shadows_section",
    "study_page",
]
