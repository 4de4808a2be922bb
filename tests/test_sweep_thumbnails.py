"""The sweep's case thumbnails: the reference's side is kept per process for the next case
judged against the same reference, and gives the bytes a fresh one gives."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from raster_oracle.oracle.sweeps import thumbnails


def _result(reference, candidate, channel):
    key = "flip" if channel == "color" else "visibility_error"
    error = np.abs(candidate - reference)
    error = error.mean(axis=-1) if error.ndim == 3 else error
    frame = SimpleNamespace(
        reference=reference, candidate=candidate, maps={key: error}, metrics={"rmse": 0.1}
    )
    record = {"channel": channel, "tone_mapping": {"exposure_stops": 0.5}}
    return SimpleNamespace(frames=[frame], record=record, reference_folders=[])


@pytest.mark.parametrize("channel", ["visibility", "color"])
def test_kept_reference_thumbnails_equal_fresh_ones(monkeypatch, channel):
    monkeypatch.setattr(thumbnails, "_KEPT", type(thumbnails._KEPT)())
    rng = np.random.default_rng(5)
    shape = (40, 64) if channel == "visibility" else (40, 64, 3)
    ref = rng.random(shape).astype(np.float32)
    cands = [np.clip(ref + rng.normal(0, 0.2, shape), 0, 1).astype(np.float32) for _ in "ab"]
    kept = [thumbnails.case_images(_result(ref, c, channel)) for c in cands]
    assert len(thumbnails._KEPT) == 1  # the reference's thumbnail, made once
    assert kept[0]["reference"] == kept[1]["reference"]
    assert kept[0]["candidate"] != kept[1]["candidate"]
    for c, got in zip(cands, kept, strict=True):
        thumbnails._KEPT.clear()
        assert thumbnails.case_images(_result(ref, c, channel)) == got
    other = thumbnails.case_images(_result(cands[0], cands[1], channel))
    assert other["reference"] == kept[0]["candidate"]  # another reference: its own thumbnail


def test_kept_parts_are_trimmed(monkeypatch):
    monkeypatch.setattr(thumbnails, "_KEPT", type(thumbnails._KEPT)())
    monkeypatch.setattr(thumbnails, "KEPT_REFERENCES", 2)
    made = []
    for k in (1, 2, 1, 3, 2):
        thumbnails._kept(k, lambda k=k: made.append(k) or k)
    assert made == [1, 2, 3, 2]  # 1 kept while recent; 2 dropped when 3 came
    assert list(thumbnails._KEPT) == [3, 2]
