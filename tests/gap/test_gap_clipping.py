"""Saturation seen in the readings: a partial session's diagnosis notes the clipped samples the
ingest counted, whatever its scope can replay."""

from __future__ import annotations

import pytest

from imucal.gap.clipping import ingest_clip_fractions, note_saturation


def summary() -> dict:
    # hand turns in raw counts that clip the gyroscope, a static recording that does not, and
    # a recording in SI units, whose range (and so its clipping) is not known
    return {
        "recordings": {
            "poses": {"samples": {"acc": 1000, "gyr": 1000}, "clipped": {"acc": 0, "gyr": 18}},
            "static": {"samples": {"acc": 3000, "gyr": 3000}, "clipped": {"acc": 0, "gyr": 0}},
            "tumble": {"samples": {"acc": 500, "gyr": 500, "mag": 500}},
        }
    }


def test_the_fraction_is_over_the_recordings_read_in_counts() -> None:
    fractions = ingest_clip_fractions(summary())
    assert fractions == {"acc": 0.0, "gyr": pytest.approx(18 / 4000)}
    assert "mag" not in fractions  # never read in counts: not known, not zero


def test_clipped_readings_are_noted_and_no_longer_called_unobservable() -> None:
    result = {
        "noted": [],
        "not_observable": {"saturation": "a static recording stays far from the ranges"},
    }
    note_saturation(result, ingest_clip_fractions(summary()))
    assert result["noted"] == ["saturation"]
    assert result["saturation"] == {"clip_fraction": {"gyr": pytest.approx(18 / 4000)}}
    assert "saturation" not in result["not_observable"]
    # nothing clipped: the diagnosis is left as it was
    quiet = {"noted": [], "not_observable": {"saturation": "far from the ranges"}}
    assert note_saturation(quiet, {"acc": 0.0, "gyr": 0.0}) == {
        "noted": [],
        "not_observable": {"saturation": "far from the ranges"},
    }
