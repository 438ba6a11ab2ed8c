"""A model term added as one module: its class and its estimator registered here, nothing else
of the package edited. The config takes its switch and option, the closed loop estimates it with
its option, the calibration applies and stores it, and it goes away with its registration."""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np
import pytest

from imucal.calibration import ImuCalibration
from imucal.gap import session as st
from imucal.gap.twin import TWIN_RECORDINGS, Twin, render_replica
from imucal.modelterms import ValueTerm, register, unregister
from imucal.pipeline.full import PipelineOptions, calibrate_session
from imucal.sim import ProtocolConfig, make_truth
from imucal.sim.effects import stream_rng
from imucal.sim.session import SENSITIVITY
from imucal.terms import TermSettings, close_loop, register_estimator, unregister_estimator


@dataclass(frozen=True)
class AccOffset(ValueTerm):
    """A constant offset of the calibrated specific force in frame B: ``a_B = v_acc - offset``."""

    name = "acc_offset"
    effect = "placement_error"
    value_field, std_field, value_shape = "offset_m_s2", "std_m_s2", (3,)
    unit = "m/s^2 (frame B)"
    report_label = "specific-force offset"
    switch_description = "a constant offset of the calibrated specific force (m/s^2, frame B)"
    options = {
        "min_rests": {"type": "integer", "minimum": 2, "default": 6,
                      "description": "fewest resting segments the offset is estimated from"},
    }  # fmt: skip

    offset_m_s2: np.ndarray
    std_m_s2: np.ndarray
    method: str = ""

    def correct(self, values, samples):
        return {**values, "acc": values["acc"] - self.offset_m_s2}

    def variance(self, values, brackets, samples):
        return {"acc": np.broadcast_to(self.std_m_s2**2, np.shape(values["acc"]))}


def fit_acc_offset(fit, *, min_rests: int) -> tuple[AccOffset | None, dict]:
    """The mean departure of the resting specific force from gravity along itself (m/s^2),
    with its standard error over the rests; refused below ``min_rests`` rests."""
    rest = st.resting_means(fit, None)
    acc = rest.acc[np.all(np.isfinite(rest.acc), axis=1)]
    if len(acc) < min_rests:
        return None, {"refused": f"{len(acc)} rests, fewer than {min_rests}"}
    g = fit.extra["options"].gravity_m_s2
    excess = acc - g * acc / np.linalg.norm(acc, axis=1, keepdims=True)
    std = excess.std(axis=0, ddof=1) / np.sqrt(len(excess))
    return AccOffset(excess.mean(axis=0), std, "resting means"), {"rests": len(acc)}


@pytest.fixture
def new_term():
    register(AccOffset)
    register_estimator(AccOffset.name, fit_acc_offset)
    yield
    unregister_estimator(AccOffset.name)
    unregister(AccOffset.name)


@pytest.fixture(scope="module")
def session():
    protocol = ProtocolConfig(static_s=60.0, run_plateau_s=3.0, run_pause_s=1.5)
    truth = make_truth("paper", stream_rng(0, "truth"))
    ratetable = {"axes": list(protocol.ratetable_axes), "rates_dps": list(protocol.rates_dps)}
    options = PipelineOptions(9.81, SENSITIVITY, {s: 32767 for s in SENSITIVITY}, ratetable)
    twin = Twin(truth, protocol, options, TWIN_RECORDINGS, True)
    imu, ref = render_replica(twin, 3, ())
    return imu, ref, options, calibrate_session(imu, ref, options).segments


def test_a_term_registered_in_one_module_is_estimated_applied_and_stored(new_term, session):
    imu, ref, options, segments = session
    settings = TermSettings.only(acc_offset="on", acc_offset_min_rests=4)
    assert settings.options["acc_offset"] == {"min_rests": 4}
    res = close_loop(imu, ref, options, segments=segments, diagnosis=None, settings=settings)
    record = res["terms"]["acc_offset"]
    assert record["included"], record["reason"]
    assert record["evidence"]["rests"] >= 4
    cal = res["calibration"]
    assert cal.terms.names() == ["acc_offset"]
    term = cal.terms.acc_offset
    # what the estimator makes of the session with the option the config gave it
    own, _ = fit_acc_offset(calibrate_session(imu, ref, options, segments), min_rests=4)
    np.testing.assert_array_equal(term.offset_m_s2, own.offset_m_s2)
    np.testing.assert_array_equal(term.std_m_s2, own.std_m_s2)
    back = ImuCalibration.from_dict(json.loads(json.dumps(cal.to_dict())))
    np.testing.assert_array_equal(back.terms.acc_offset.offset_m_s2, term.offset_m_s2)
    readings = {"acc": np.ones((4, 3)), "gyr": np.zeros((4, 3)), "mag": np.ones((4, 3))}
    units = {"acc": "m/s^2", "gyr": "rad/s", "mag": "normalised"}
    with_term = back.calibrate(readings, units)[0]["acc"]
    paper = ImuCalibration(back.acc, back.gyr, back.mag).calibrate(readings, units)[0]["acc"]
    np.testing.assert_allclose(with_term, paper - term.offset_m_s2)


def test_a_term_refused_by_its_estimator_stays_out_of_the_model(new_term, session):
    imu, ref, options, segments = session
    settings = TermSettings.only(acc_offset="on", acc_offset_min_rests=1000)
    res = close_loop(imu, ref, options, segments=segments, diagnosis=None, settings=settings)
    assert res["calibration"] is None
    assert "refused:" in res["terms"]["acc_offset"]["reason"]
    assert "fewer than 1000" in res["terms"]["acc_offset"]["reason"]


def test_the_config_forgets_a_term_with_its_registration():
    with pytest.raises(ValueError, match="unknown terms settings 'acc_offset'"):
        TermSettings.from_config(acc_offset="on")
