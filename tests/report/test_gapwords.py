"""The gap diagnosis's words: every effect of the catalogue and every statistic the diagnosis
scores has its plain label, unit and size formatter, and the sizes read in physical units."""

import dataclasses
import re

import numpy as np
import pytest

from imucal.gap.catalogue import catalogue
from imucal.gap.statistics import CATALOGUE
from imucal.report import gapwords
from imucal.sim.effects import EFFECTS

#: A number followed by a unit (or a percentage) in a size phrase.
WITH_UNIT = re.compile(r"\d(?: × 10[⁻⁰¹²³⁴⁵⁶⁷⁸⁹]+)? ?(%|°|[a-zA-Zµ(])")


def test_every_effect_of_the_catalogue_has_its_words():
    missing = [name for name in catalogue() if name not in gapwords.EFFECTS]
    stale = [name for name in gapwords.EFFECTS if name not in catalogue()]
    assert missing == [] and stale == [], (missing, stale)
    for name, words in gapwords.EFFECTS.items():
        assert words.label and "_" not in words.label, name
        assert callable(words.size), name


def test_every_statistic_has_a_plain_label_and_a_unit():
    missing = [name for name in CATALOGUE if name not in gapwords.STATISTICS]
    stale = [name for name in gapwords.STATISTICS if name not in CATALOGUE]
    assert missing == [] and stale == [], (missing, stale)
    for name, words in gapwords.STATISTICS.items():
        # a label for a person, short enough for a figure's axis; "" only for a pure number
        assert words.label and "_" not in words.label and len(words.label) <= 34, name
        if CATALOGUE[name].unit not in ("1",):
            assert words.unit, name


def test_every_stage_and_sensor_of_a_signature_has_words():
    for name, entry in catalogue().items():
        for locations in entry.estimated.values():
            for stage, sensor, _ in locations:
                assert stage in gapwords.STAGE_WORDS, (name, stage)
                assert sensor in gapwords.SENSOR_WORDS, (name, sensor)


@pytest.mark.parametrize("name", sorted(EFFECTS))
def test_the_realistic_size_of_every_effect_reads_in_physical_units(name):
    effect = EFFECTS[name]()
    params = {f.name: getattr(effect, f.name) for f in dataclasses.fields(effect)}
    text = gapwords.effect_size(name, params)
    assert WITH_UNIT.search(text), (name, text)
    assert "_" not in text, (name, text)


def test_sizes_of_the_demo_effects():
    # the demo's two effects as its diagnosis estimates them (data/demo/README.md)
    offset = gapwords.effect_size("time_offset", {"offset_s": 0.31996, "drift_ppm": 10.26})
    assert offset == "the reference started 0.32 s before the module, its clock drifts 10.3 ppm"
    loss = gapwords.effect_size(
        "packet_loss", {"fraction": 0.004466, "model": "gilbert", "burst_mean": 3.595}
    )
    assert loss == "0.45 % of the packets lost in bursts of 3.6 packets on average"
    # a negative offset: the reference started after the module; a short one in ms
    late = gapwords.effect_size("time_offset", {"offset_s": -0.012})
    assert late == "the reference started 12 ms after the module"


def test_a_matrix_and_a_vector_size_by_their_largest_entry():
    g = np.zeros((3, 3))
    g[1, 2] = -2e-4
    text = gapwords.effect_size("g_sensitivity", {"matrix": g.tolist()})
    # 2e-4 rad/s per m/s^2 is 0.112 deg/s per g
    assert (
        text == "gyroscope rate per specific force up to 2 × 10⁻⁴ (rad/s)/(m/s²) (0.112 °/s per g)"
    )
    drift = gapwords.effect_size(
        "temperature_drift", {"gyr_per_k": [0.0, -1e-4, 5e-5], "acc_per_k": [0.0, 0.0, 0.0]}
    )
    assert drift == "bias drift: gyroscope up to 1 × 10⁻⁴ rad/s per K (0.00573 °/s per K)"
    # the temperature it follows: a warm-up that is an estimate, or the recorded path (a
    # refused warm-up fit leaves no rise or time constant to print)
    warm = gapwords.effect_size(
        "temperature_drift", {"gyr_per_k": [0.0, 1e-4, 0.0], "rise_c": 4.0, "tau_s": 300.0}
    )
    assert warm.endswith("over a warm-up of 4 K with a time constant of 300 s")
    path = gapwords.effect_size(
        "temperature_drift", {"gyr_per_k": [0.0, 1e-4, 0.0], "path_c": [4.9, 5.2, 16.2, 15.9]}
    )
    assert path.endswith("on the recorded temperature, 4.9-16.2 °C (no warm-up curve fits it)")
    assert "time constant" not in path


def test_locations_in_words():
    location = {"stage": "gyr_table", "sensor": "gyr", "axis": "y", "segment": "run",
                "statistic": "rate2"}  # fmt: skip
    assert gapwords.location_label(location) == (
        "residual ∝ rate² (1/(rad/s)): gyroscope y, rate table, run"
    )
    clock = {"stage": "ingest", "sensor": "clock", "axis": "-", "segment": "all",
             "statistic": "loss_fraction"}  # fmt: skip
    assert gapwords.location_label(clock) == "share of packets lost: clock, packets"
    # a statistic in the sensor's unit takes the unit of the location's sensor
    assert gapwords.statistic_unit("trend_per_s", "acc") == "m/s²/s"
    assert gapwords.statistic_unit("trend_per_s", "gyr") == "rad/s/s"


@pytest.mark.parametrize(
    ("value", "text"),
    [(0.31996, "0.32"), (1442497.35, "1.44 × 10⁶"), (0.0, "0"), (33.48, "33.5"),
     (-4.2e-6, "-4.2 × 10⁻⁶"), (120.0, "120")],
)  # fmt: skip
def test_numbers(value, text):
    assert gapwords.number(value) == text
