"""Temperature drift in a static recording's diagnosis: the magnetometer's coefficient, the
warm-up curve's physical bounds (imucal.gap.library.thermal).

Sessions are the static recordings of ``test_gap_static`` (300 s, acc/gyro at 100 Hz and the
magnetometer at 75 Hz, rows apart), rendered by the simulator with a known ``temperature_drift``.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import z_limit
from test_gap_static import DURATION_S, diagnose_sim, static_session

from imucal.gap.library import scope_library
from imucal.gap.library.thermal import fit_warm_up, warm_up_params
from imucal.gap.streams import split_streams
from imucal.report.gapwords import effect_size
from imucal.sim import make_effect
from imucal.sim.effects import RecordingContext

#: A magnetometer bias drift of its own on each axis, either sign (normalised field per K):
#: 4 K of warm-up move it by up to 1.6e-3, about 10 of its slope's std in 300 s.
MAG_PER_K = np.array([4e-4, -2.5e-4, 1.5e-4])


def _mag_drift(**warm) -> object:
    warm = {"start_c": 25.0, "rise_c": 4.0, "tau_s": 100.0, **warm}
    return make_effect(
        "temperature_drift", acc_per_k=0.0, gyr_per_k=0.0, mag_per_k=MAG_PER_K,
        acc_scale_per_k=0.0, gyr_scale_per_k=0.0, **warm,
    )  # fmt: skip


def _estimate(table):
    return scope_library("static")["temperature_drift"].estimate(split_streams(table), None)


def test_the_magnetometer_coefficient_comes_back_with_an_honest_std(rms_z_band):
    """Over 20 seeds, (estimate - truth) / reported std per axis: RMS within the chi-square band
    of 60 z-scores (a std off by a factor of 1.6 either way leaves it), each within the
    Bonferroni bound of Student's t at the fit's 14 dof."""
    effect = _mag_drift()
    z = []
    for seed in range(20):
        est = _estimate(static_session(100 + seed, (effect,)))
        std = np.asarray(est.evidence["mag_per_k_std"])
        z.append((np.asarray(est.params["mag_per_k"]) - MAG_PER_K) / std)
    z = np.ravel(z)
    low, high = rms_z_band(len(z))
    assert low < np.sqrt(np.mean(z**2)) < high
    assert np.max(np.abs(z)) < z_limit(len(z), dof=14)


def test_a_drift_of_the_magnetometer_alone_is_named_and_estimated(z_bound):
    d = diagnose_sim(static_session(6, (_mag_drift(),)))
    assert any(
        loc["statistic"] == "temp_slope" and loc["sensor"] == "mag" for loc in d["locations"]
    )
    assert "temperature_drift" in d["explained"]
    drift = next(e for e in d["effects"] if e["name"] == "temperature_drift")
    est = _estimate(static_session(6, (_mag_drift(),)))
    std = np.asarray(est.evidence["mag_per_k_std"])
    z = (np.asarray(drift["params"]["mag_per_k"]) - MAG_PER_K) / std
    assert np.all(np.abs(z) < z_bound(3, dof=14))
    assert drift["flags"] == []  # the warm-up (tau 100 s in 300 s) is an estimate


@pytest.mark.parametrize("seed", [11, 12, 13, 14])
def test_a_clean_session_names_no_temperature_drift(seed):
    """The false-alarm side: a clean session with the same temperature channel (a cooling of
    0.3 K) names no temperature drift, of the magnetometer or another sensor."""
    d = diagnose_sim(static_session(seed))
    assert "temperature_drift" not in d["explained"]


def test_a_warm_up_inside_the_recording_is_an_estimate():
    t = np.linspace(0.0, 600.0, 601)
    temp = np.round(20.0 + 6.0 * (1 - np.exp(-t / 150.0)), 2)
    warm = fit_warm_up(t, temp)
    assert warm.refused == ""
    # rounded to 0.01 K over 601 samples: the curve's parameters to well under a percent
    assert warm.tau_s == pytest.approx(150.0, rel=0.01)
    assert warm.rise_c == pytest.approx(6.0, rel=0.01)


def test_a_time_constant_beyond_the_recording_is_refused_with_the_reason():
    """A warm-up whose time constant is 50 times the recording's length is a ramp in it: its
    rise and time constant trade against each other (the fit that reported 3e6 K and 1.8e10 s
    on a real tag); neither is reported, and the drift follows the recorded path."""
    t = np.linspace(0.0, 600.0, 601)
    temp = np.round(20.0 + 100.0 * (1 - np.exp(-t / 30000.0)), 2)
    warm = fit_warm_up(t, temp)
    assert "beyond the recording's length 600 s" in warm.refused
    params, flags = warm_up_params(t, temp)
    assert "rise_c" not in params and "tau_s" not in params
    assert len(flags) == 1 and flags[0].startswith("warm-up fit refused (")
    assert params["path_c"][0] == pytest.approx(20.0, abs=0.05)
    assert params["path_span_s"] == pytest.approx(600.0)


def test_a_channel_that_is_no_warm_up_is_refused():
    """A temperature cycled down and up (a climate chamber): no warm-up curve describes it."""
    t = np.linspace(0.0, 3600.0, 3601)
    temp = 20.0 - 8.0 * np.sin(np.pi * t / 3600.0)
    warm = fit_warm_up(t, temp)
    assert warm.refused
    params, _ = warm_up_params(t, temp)
    # the path holds the cycle: its lowest value is the channel's, within a window's mean
    assert min(params["path_c"]) == pytest.approx(12.0, abs=0.05)


def test_a_ramp_is_flagged_in_the_diagnosis_and_not_printed_as_a_warm_up():
    """A gyro drift on a warm-up 30 times longer than the recording: the drift is still named
    (rendered on the recorded path), the record's flag gives the reason, and the report's
    words say the drift follows the recorded temperature, with no rise or time constant."""
    k = np.array([3e-4, -2e-4, 1e-4])
    effect = make_effect(
        "temperature_drift", start_c=25.0, rise_c=120.0, tau_s=30 * DURATION_S, acc_per_k=0.0,
        gyr_per_k=k, acc_scale_per_k=0.0, gyr_scale_per_k=0.0,
    )  # fmt: skip
    d = diagnose_sim(static_session(6, (effect,)))
    drift = next(e for e in d["effects"] if e["name"] == "temperature_drift")
    assert drift["accepted"]
    assert len(drift["flags"]) == 1 and "warm-up fit refused" in drift["flags"][0]
    assert "rise_c" not in drift["params"] and "tau_s" not in drift["params"]
    words = effect_size("temperature_drift", drift["params"])
    assert "recorded temperature" in words and "time constant" not in words


def test_the_simulator_follows_a_recorded_path():
    """``path_c``: the temperature interpolated between evenly spaced values on the session
    clock, held at its ends; a path of one value or without a span is refused."""
    effect = make_effect("temperature_drift", path_c=[10.0, 4.0, 16.0], path_span_s=200.0)
    ctx = RecordingContext("static", 10.0, 50.0, {}, 0)
    # samples at 0, 50, 150, 250 s after the recording's start: 100, 150, 200, 300 s
    temp = effect.temperature_c(np.array([500, 1000, 1500, 2500]), ctx)
    np.testing.assert_allclose(temp, [4.0, 10.0, 16.0, 16.0])
    with pytest.raises(ValueError, match="path_c needs at least 2"):
        make_effect("temperature_drift", path_c=[10.0], path_span_s=200.0)
    with pytest.raises(ValueError, match="path_span_s > 0"):
        make_effect("temperature_drift", path_c=[10.0, 11.0])


def test_a_rise_beyond_what_the_span_allows_is_refused(monkeypatch):
    """With a time constant within the recording, the curve shows at least 1 - 1/e of its rise
    there: a fitted rise beyond span / (1 - 1/e) is beyond what the recording could show (the
    fit's result is replaced here, as no least-squares fit of a warm-up gives one)."""
    from imucal.gap.library import thermal

    t = np.linspace(0.0, 600.0, 601)
    temp = 20.0 + 2.0 * (1 - np.exp(-t / 150.0))  # span 1.96 K: at most 3.11 K of rise
    monkeypatch.setattr(thermal, "curve_fit", lambda *a, **k: ((20.0, 3.5, 300.0), None))
    assert "rise 3.5 K beyond 3.11 K" in fit_warm_up(t, temp).refused
    monkeypatch.setattr(thermal, "curve_fit", lambda *a, **k: ((20.0, 3.0, 300.0), None))
    assert "rise" not in fit_warm_up(t, temp).refused
