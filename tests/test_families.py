"""The family records of the technique registry: one place the CLI, sweeps, scoring and
reports read a family from, its metrics taken from the metric catalogue."""

from __future__ import annotations

import pytest
from raster_oracle.metrics.catalog import CATALOG
from raster_oracle.oracle.scoring.score import REFERENCE_GROUPS
from raster_oracle.oracle.scoring.technique import technique_channels
from raster_oracle.oracle.sweeps.report import family_defaults

from raster_oracle import raster_models


def test_every_technique_belongs_to_a_registered_family():
    for t in raster_models.TECHNIQUES.values():
        assert t.family in raster_models.FAMILIES, t.name
        assert raster_models.family(t.name) is raster_models.FAMILIES[t.family]


@pytest.mark.parametrize("name", list(raster_models.FAMILIES))
def test_family_metrics_come_from_the_catalogue_and_channels_are_scorable(name):
    fam = raster_models.FAMILIES[name]
    assert fam.metrics and all(m in CATALOG for m in fam.metrics)
    assert fam.extremes_metric is None or fam.extremes_metric in CATALOG
    assert fam.channels and all(c in REFERENCE_GROUPS for c in fam.channels)
    assert fam.coverage_channel is None or fam.coverage_channel in REFERENCE_GROUPS
    assert fam.memory_cost and fam.costs


def test_channels_fronts_and_report_defaults_are_read_from_the_record():
    assert technique_channels("csm") == ("visibility",)
    assert technique_channels("msaa") == ("color", "coverage")
    assert raster_models.front_group("csm") == "shadow maps"
    assert raster_models.front_group("izb") == "izb"
    assert raster_models.front_group("fxaa") == "anti-aliasing"
    defaults = family_defaults()
    assert defaults["aa"]["metrics"][0] == "flip_mean"
    assert defaults["shadow"]["costs"][0] == "memory_bytes"


def test_unknown_family_names_the_valid_ones():
    with pytest.raises(raster_models.ModelError, match="choose one of shadow, aa"):
        raster_models.family("nope")
