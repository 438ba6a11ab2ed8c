"""Every model term's dict form and report rows, pinned and round-tripped; the declarations the
loops over the terms read (what apply hands a term, what it writes of its flags, what the
held-out check reads), checked on every registered term and refused when malformed."""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass

import numpy as np
import pandas as pd
import pytest

from imucal import errormodel
from imucal.calibration import ImuCalibration, SensorCalibration
from imucal.columns import ACC, GYR, MAG, SI_COLUMN_UNITS, TIME
from imucal.modelterms import (
    GSensitivity,
    LeverArm,
    MagDelay,
    ModelTerms,
    TemperaturePolynomial,
    TemperatureTerm,
)
from imucal.modelterms.contract import ReportRow, ValueTerm
from imucal.modelterms.registry import declaration_problems, register, registered_terms, unregister
from imucal.pipeline.stages import apply_calibration
from imucal.terms.heldout import heldout_comparison

G_UNIT = "rad/s per m/s^2 (frame B; row: gyro axis, column: specific-force axis)"
R_UNIT = "m (frame B; accelerometer relative to the rate table's rotation centre)"
G = [[2e-4, 1e-5, 0.0], [0.0, -1e-4, 3e-6], [1e-6, 0.0, 1e-4]]
G_STD = [[5e-6] * 3, [6e-6] * 3, [7e-6] * 3]


def _temperature() -> TemperatureTerm:
    acc = TemperaturePolynomial("acc", 25.0, (20.0, 30.0), 1.0, [[3e-3, -3e-3, 3e-3]],
                                [[2e-4, 1e-4, -1e-4]], [[2e-4] * 3], [[2e-5] * 3], "held out",
                                np.full((3, 1, 1), 4e-8))  # fmt: skip
    gyr = TemperaturePolynomial("gyr", 25.0, (21.5, 28.0), 0.5,
                                [[5e-4, -5e-4, 5e-4], [1e-5, 2e-5, -1e-5]], np.zeros((0, 3)),
                                [[3e-5] * 3, [1e-6] * 3], np.zeros((0, 3)))  # fmt: skip
    return TemperatureTerm({"acc": acc, "gyr": gyr})


#: One example of every registered term (a new term adds its own).
EXAMPLES = {
    "temperature": _temperature(),
    "g_sensitivity": GSensitivity(G, G_STD, "resting means"),
    "lever_arm": LeverArm([0.03, 0.02, 0.0], [2e-4, 3e-4, 1e-4], "rate table"),
    "mag_delay": MagDelay(0.0594, 0.0012, "rotation phases"),
}


def test_every_registered_term_has_an_example():
    assert sorted(EXAMPLES) == sorted(t.name for t in registered_terms())


@pytest.mark.parametrize("name", sorted(EXAMPLES))
def test_every_term_round_trips_through_its_dict_form_with_the_same_report_rows(name):
    term = EXAMPLES[name]
    text = json.dumps(term.to_dict())
    back = type(term).from_dict(json.loads(text))
    assert json.dumps(back.to_dict()) == text
    assert back.report_rows() == term.report_rows()
    assert json.dumps(ModelTerms(**{name: back}).to_dict()) == json.dumps({name: term.to_dict()})


def test_the_value_terms_dict_forms_and_report_rows_are_as_written_in_calibration_json():
    """The keys in their order, the units and the report rows of the terms behind
    :class:`ValueTerm`, written out: calibration.json and the report do not move."""
    g, r, m = EXAMPLES["g_sensitivity"], EXAMPLES["lever_arm"], EXAMPLES["mag_delay"]
    assert json.dumps(g.to_dict()) == json.dumps(
        {"matrix": G, "std": G_STD, "unit": G_UNIT, "method": "resting means"}
    )
    assert json.dumps(r.to_dict()) == json.dumps(
        {"r_m": [0.03, 0.02, 0.0], "std_m": [2e-4, 3e-4, 1e-4], "unit": R_UNIT,
         "method": "rate table"}
    )  # fmt: skip
    assert json.dumps(m.to_dict()) == json.dumps(
        {"delay_s": 0.0594, "std_s": 0.0012, "unit": "s", "method": "rotation phases"}
    )
    assert g.report_rows() == [ReportRow("g-sensitivity G", G, G_STD, G_UNIT)]
    assert r.report_rows() == [
        ReportRow("lever arm r", [0.03, 0.02, 0.0], [2e-4, 3e-4, 1e-4], R_UNIT)
    ]
    assert m.report_rows() == [ReportRow("magnetometer delay", 0.0594, 0.0012, "s")]
    assert type(m.delay_s) is float and type(m.to_dict()["std_s"]) is float


def test_the_temperature_terms_report_rows_are_one_per_sensor_kind_and_order():
    rows = EXAMPLES["temperature"].report_rows()
    assert [row.name for row in rows] == [
        "temperature acc bias dT^1", "temperature acc scale dT^1",
        "temperature gyr bias dT^1", "temperature gyr bias dT^2",
    ]  # fmt: skip
    assert rows[2] == ReportRow("temperature gyr bias dT^1", [5e-4, -5e-4, 5e-4], [3e-5] * 3,
                                "rad/s/K^k (row k-1: coefficient of (T - reference_c)^k)")  # fmt: skip


def test_value_terms_refuse_malformed_coefficients_and_a_missing_key():
    with pytest.raises(ValueError, match=r"g_sensitivity\.matrix must be a finite 3x3 matrix"):
        GSensitivity(np.eye(2), np.zeros((3, 3)))
    with pytest.raises(ValueError, match=r"lever_arm\.std_m must be 3 finite values, got"):
        LeverArm([0.0, 0.0, 0.0], [0.0, np.inf, 0.0])
    with pytest.raises(ValueError, match=r"mag_delay\.delay_s must be finite, got nan"):
        MagDelay(np.nan, 0.0)
    with pytest.raises(ValueError, match="lever_arm term lacks the key 'r_m'"):
        LeverArm.from_dict({"std_m": [0, 0, 0]})
    bare = MagDelay.from_dict({"delay_s": 0.01})
    assert (bare.std_s, bare.method) == (0.0, "")
    np.testing.assert_array_equal(GSensitivity.from_dict({"matrix": G}).std, np.zeros((3, 3)))


@dataclass(frozen=True)
class FieldRamp(ValueTerm):
    """A toy term: a field growing in time in the calibrated magnetometer,
    ``m_B = v_mag - t_s ramp``; it reads the sample times, flags samples after 0.2 s and holds
    out a residual of its own."""

    name = "field_ramp"
    effect = "platform_magnetic"
    needs = frozenset({"t_s"})
    heldout_residual = "the toy's residual (normalised)"
    value_field, std_field, value_shape = "ramp", "ramp_std", (3,)
    unit = "normalised/s"
    report_label = "field ramp"
    switch_description = "a field that ramps in time (normalised/s)"

    ramp: np.ndarray
    ramp_std: np.ndarray
    method: str = ""

    def check(self, samples):
        late = int(np.sum(samples.t_s > 0.2))
        return {"late": late} if late else {}

    def flag_report(self, flags, source):
        return {"field_ramp_late": flags}, [f"{source}: {flags['late']} samples after 0.2 s"]

    def correct(self, values, samples):
        return {**values, "mag": values["mag"] - samples.t_s[:, None] * self.ramp}

    def variance(self, values, brackets, samples):
        return {"mag": (samples.t_s[:, None] * self.ramp_std) ** 2}


RAMP = np.array([0.1, -0.2, 0.3])


@pytest.fixture
def ramp():
    register(FieldRamp)
    yield FieldRamp(RAMP, np.full(3, 0.01))
    unregister(FieldRamp.name)


def _recording(n: int = 40) -> tuple[pd.DataFrame, dict]:
    rng = np.random.default_rng(5)
    cols = {TIME: np.arange(n) / 100.0}
    for c in (*ACC, *GYR, *MAG):
        cols[c] = rng.normal(0.0, 1.0, n)
    return pd.DataFrame(cols), {"units": SI_COLUMN_UNITS, "source": "toy.parquet"}


def _calibration(terms: ModelTerms) -> ImuCalibration:
    m = errormodel.compose([1.1, 0.9, 1.0], [0.01, -0.02, 0.005], [0.02, 0.01, -0.03])
    return ImuCalibration(SensorCalibration("acc", [0.1, 0.2, 0.3], m, "m/s^2"),
                          SensorCalibration("gyr", [0.01, 0.02, 0.03], m, "rad/s"),
                          SensorCalibration("mag", [0.1, -0.1, 0.2], m, "normalised"), terms)  # fmt: skip


def test_apply_hands_a_term_what_it_needs_and_writes_what_it_reports_of_its_flags(ramp, caplog):
    table, meta = _recording()
    paper, _ = apply_calibration(table, meta, _calibration(ModelTerms()))
    with caplog.at_level(logging.WARNING):
        out, m = apply_calibration(table, meta, _calibration(ModelTerms(field_ramp=ramp)))
    t = table[TIME].to_numpy()
    np.testing.assert_allclose(out[list(MAG)].to_numpy(),
                               paper[list(MAG)].to_numpy() - t[:, None] * RAMP, rtol=0, atol=1e-15)  # fmt: skip
    assert m["model_terms"] == ["field_ramp"]
    assert m["field_ramp_late"] == {"late": int(np.sum(t > 0.2))} == {"late": 19}
    assert "toy.parquet: 19 samples after 0.2 s" in caplog.text


def test_heldout_comparison_reads_the_terms_own_residual_and_effect(ramp):
    evidence = {"heldout_rms": {"without": 1.0, "with": 0.5, "values": 16}}
    diagnosis = {"effects": [{"name": "platform_magnetic", "heldout_shrink": 0.7}]}
    h = heldout_comparison("field_ramp", evidence, diagnosis)
    assert h["residual"] == "the toy's residual (normalised)"
    assert (h["achieved_shrink"], h["achieved_std"]) == pytest.approx((0.75, 0.125))
    assert h["predicted_shrink"] == 0.7 and h["short_of_prediction"] is False
    # the temperature term reads its estimator's evidence per sensor
    evidence = {"acc": {"heldout_rms": {"bias 0, scale none": 1.0, "bias 1, scale none": 0.4},
                        "without": "bias 0, scale none", "with": "bias 1, scale none",
                        "segments": 12}}  # fmt: skip
    h = heldout_comparison("temperature", evidence, None)
    assert h["residual"] == TemperatureTerm.heldout_residual
    assert (h["rms_without"], h["rms_with"], h["values"]) == (1.0, 0.4, 12)
    assert "note" in heldout_comparison("mag_delay", {"heldout_rms": {"without": 1.0,
                                                                      "with": 0.5}}, None)  # fmt: skip


def test_every_registered_term_declares_what_the_loops_read():
    for term in registered_terms():
        assert declaration_problems(term) == [], term.name


def _misdeclared(**attrs) -> type:
    """A concrete toy term with ``attrs`` in place of its declarations."""
    return dataclass(frozen=True)(type("Misdeclared", (FieldRamp,), {"name": "misdeclared",
                                                                    **attrs}))  # fmt: skip


@pytest.mark.parametrize(
    "attrs, message",
    [
        ({"needs": frozenset({"temperature"})}, r"needs \['temperature'\], not among"),
        ({"needs": "t_s"}, "needs is not a frozenset"),
        ({"heldout_residual": None}, "reads a held-out RMS .* but declares no heldout_residual"),
        ({"value_field": "ramp_m"}, "value_field 'ramp_m' is not one of its fields"),
        ({"report_label": ""}, "no report_label"),
        ({"value_shape": 3}, "value_shape 3 is not a tuple"),
    ],
)
def test_a_term_missing_a_declaration_the_loops_read_is_refused(attrs, message):
    if attrs.get("heldout_residual", 1) is None:
        attrs["heldout_rms"] = classmethod(lambda cls, evidence: None)
    term = _misdeclared(**attrs)
    with pytest.raises(ValueError, match=f"model term Misdeclared: .*{message}"):
        register(term)
    assert "misdeclared" not in {t.name for t in registered_terms()}
