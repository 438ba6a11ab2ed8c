"""The model-term contract: a term registered here, in the test, is applied, serialised, shown
in the report and named by the exports without any other module knowing it; every registered
term has each part of the contract."""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np
import pytest
import yaml

from imucal import errormodel
from imucal.calibration import ImuCalibration, SensorCalibration
from imucal.columns import ACC, GYR, TIME
from imucal.gap.catalogue import contract_violations, term_of_effect
from imucal.modelterms import (
    ModelTerm,
    ModelTerms,
    ReportRow,
    register,
    registered_terms,
    settings_schema,
    unregister,
)
from imucal.terms.estimators import missing_estimators
from imucal.terms.selection import TermSettings


@dataclass(frozen=True)
class FieldOffset(ModelTerm):
    """A toy term: a constant field in B added to the calibrated magnetometer,
    ``m_B = v_mag - offset``; Kalibr (in this test's fiction) carries it."""

    name = "field_offset"
    effect = "platform_magnetic"
    exported_by = frozenset({"kalibr"})
    switch_description = "a constant field offset (normalised)"

    offset: np.ndarray
    std: np.ndarray

    def correct(self, values, samples):
        return {**values, "mag": values["mag"] - self.offset}

    def variance(self, values, brackets, samples):
        return {"mag": np.broadcast_to(np.asarray(self.std) ** 2, np.shape(values["mag"]))}

    def to_dict(self):
        return {"offset": list(map(float, self.offset)), "std": list(map(float, self.std)),
                "unit": "normalised"}  # fmt: skip

    @classmethod
    def from_dict(cls, d):
        return cls(np.asarray(d["offset"], dtype=float), np.asarray(d["std"], dtype=float))

    def report_rows(self):
        return [ReportRow("field offset", self.to_dict()["offset"], self.to_dict()["std"],
                          "normalised")]  # fmt: skip


OFFSET = np.array([0.03, -0.01, 0.02])
OFFSET_STD = np.array([1e-3, 2e-3, 3e-3])


@pytest.fixture
def toy():
    """The toy term registered for one test, and removed after it."""
    register(FieldOffset)
    yield FieldOffset(OFFSET, OFFSET_STD)
    unregister(FieldOffset.name)


def _calibration(terms: ModelTerms | None = None) -> ImuCalibration:
    m = errormodel.compose([1.1, 0.9, 1.0], [0.01, -0.02, 0.005], [0.02, 0.01, -0.03])
    return ImuCalibration(
        SensorCalibration("acc", [0.1, 0.2, 0.3], m, "m/s^2"),
        SensorCalibration("gyr", [0.01, 0.02, 0.03], m, "rad/s"),
        SensorCalibration("mag", [0.1, -0.1, 0.2], m, "normalised"),
        terms or ModelTerms(),
    )


UNITS = {"acc": "m/s^2", "gyr": "rad/s", "mag": "normalised"}


def _readings(n: int = 20) -> dict:
    rng = np.random.default_rng(11)
    return {s: rng.normal(0, 1, (n, 3)) for s in ("acc", "gyr", "mag")}


def test_a_registered_term_is_applied_with_its_variance(toy):
    readings = _readings()
    paper, _ = _calibration().calibrate(readings, UNITS)
    cal = _calibration(ModelTerms(field_offset=toy))
    values, flags = cal.calibrate(readings, UNITS)
    assert flags == {}
    np.testing.assert_array_equal(values["mag"], paper["mag"] - OFFSET)
    for s in ("acc", "gyr"):
        np.testing.assert_array_equal(values[s], paper[s])
    variance = cal.parameter_variance(readings)
    assert set(variance) == {"mag"}
    np.testing.assert_array_equal(variance["mag"], np.tile(OFFSET_STD**2, (20, 1)))


def test_a_registered_term_round_trips_through_calibration_json(toy):
    cal = _calibration(ModelTerms(field_offset=toy))
    text = json.dumps(cal.to_dict())
    assert json.loads(text)["terms"] == {"field_offset": toy.to_dict()}
    back = ImuCalibration.from_dict(json.loads(text))
    assert back.terms.names() == ["field_offset"]
    np.testing.assert_array_equal(back.terms.field_offset.offset, OFFSET)
    assert json.dumps(back.to_dict()) == text
    readings = _readings()
    np.testing.assert_array_equal(back.calibrate(readings, UNITS)[0]["mag"],
                                  cal.calibrate(readings, UNITS)[0]["mag"])  # fmt: skip


def test_an_unregistered_term_is_refused_by_name():
    d = _calibration().to_dict()
    d["terms"] = {"field_offset": {"offset": [0, 0, 0], "std": [0, 0, 0]}}
    with pytest.raises(ValueError, match=r"unknown model terms \['field_offset'\]"):
        ImuCalibration.from_dict(d)


def test_a_registered_term_is_in_the_reports_coefficients(toy, tmp_path):
    from imucal.report.sections import terms_section

    cal = _calibration(ModelTerms(field_offset=toy))
    summary = {"format_version": 1, "in_model": ["field_offset"],
               "terms": {"field_offset": {"setting": "on", "included": True,
                                          "reason": "on in the config"}},
               "calibration": cal.to_dict()}  # fmt: skip
    (tmp_path / "terms.json").write_text(json.dumps(summary))
    (tmp_path / "after.json").write_text(json.dumps({"note": "toy"}))
    ctx = terms_section([tmp_path / "terms.json", tmp_path / "after.json"], None)
    assert ctx["coefficients"] == [{"term": "field offset", "unit": "normalised",
                                    "value": "[0.03, -0.01, 0.02] ± [0.001, 0.002, 0.003]"}]  # fmt: skip


def _noise() -> dict:
    """noise.json of one minute of white noise, what every export needs beside the
    calibration."""
    from imucal.noise import characterise_noise

    rng = np.random.default_rng(2)
    n = 6000
    cols = {TIME: np.arange(n) / 100.0}
    for name in (*ACC, *GYR):
        cols[name] = 1e-2 * rng.standard_normal(n)
    return characterise_noise(cols.__getitem__, list(cols), recording="static", window_s=None,
                              min_duration_s=30.0, level=0.683)  # fmt: skip


def test_a_registered_term_is_named_by_the_exports_that_cannot_carry_it(toy):
    from imucal.export import export_files

    calibration = _calibration(ModelTerms(field_offset=toy)).to_dict()
    noise = _noise()
    said = "NOT in this file: the model terms field_offset of calibration.json"
    for fmt, carried in (("kalibr", True), ("openvins", False), ("ros", False)):
        for name, text in export_files(fmt, calibration, noise).items():
            yaml.safe_load(text)
            if name != "imu.yaml":  # Kalibr's noise file holds no calibration
                assert (said in text) != carried, (fmt, name)


def test_every_registered_term_has_each_part_of_the_contract():
    """An effect the protocol's diagnosis estimates, an estimator, and a config switch with its
    default and its options in the config's schema (the methods are checked when the class is
    registered: an abstract one left refuses it; the round trip of every term:
    tests/test_calibration.py)."""
    assert not contract_violations()
    assert not missing_estimators()
    schema = settings_schema()["properties"]
    settings = TermSettings.from_config()
    for term in registered_terms():
        assert term_of_effect()[term.effect] == term.name
        assert schema[term.name]["default"] == settings.switch(term.name) == "auto"
        assert set(settings.options[term.name]) == set(term.options), term.name
        for option in term.options:
            assert f"{term.name}_{option}" in schema, (term.name, option)


def test_a_registered_term_has_a_config_switch(toy):
    assert TermSettings.from_config(field_offset="on").switch("field_offset") == "on"
    assert "field_offset" in TermSettings.from_config().wanted()
    assert settings_schema()["properties"]["field_offset"]["description"].startswith(
        "a constant field offset (normalised): off, on, or auto"
    )


def test_a_term_without_every_part_is_refused():
    class Incomplete(ModelTerm):  # no estimator, variance, dict form nor report rows
        name = "incomplete"
        effect = "shock"

    with pytest.raises(ValueError, match="concrete subclass of ModelTerm"):
        register(Incomplete)
    with pytest.raises(ValueError, match="registered already"):
        register(registered_terms()[0])
    assert "incomplete" not in term_of_effect().values()
