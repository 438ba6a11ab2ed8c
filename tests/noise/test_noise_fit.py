"""IEEE 952 fits: known N, B, K recovered from 3 h at 100 Hz (synthetic and simulated)."""

from __future__ import annotations

import numpy as np
import pytest
from synthetic import synthetic_rate

from imucal.columns import ACC, GYR, TIME
from imucal.noise import characterise_noise, fit_noise_terms, overlapping_adev, sensor_noise

RATE = 100.0
N_3H = int(3 * 3600 * RATE)
LEVEL = 0.683


#: Relative spread (std over seeds 0-29) of the fitted N, B and K of the 3 h design below.
SPREAD_3H = {"N": 0.0011, "B": 0.017, "K": 0.13}


def test_synthetic_three_hours_recover_n_b_k():
    """N, B and K within 4.5 times their estimator's spread.

    The terms are chosen so that each dominates several octaves of a 3 h record (N up to 3 s,
    B from 3 s to 100 s, K beyond): N = 2e-4 rad/s/sqrt(Hz), B = 1.74e-4 rad/s (36 deg/h),
    K = 2e-5 rad/s^2/sqrt(Hz). Over seeds 0-29 of this design the relative errors had the
    spread :data:`SPREAD_3H` (means 0.07 %, 0.01 %, 0.4 %, within their sampling error); 4.5
    spreads (a normal error beyond them: 7e-6) give 0.5 %, 7.7 % and 59 %. The acceptance
    bounds of 10 % (N) and 25 % (B, K) are not a property of this record for K: 2 of the 30
    seeds miss 25 % (by 28 % and 25.1 %). The fit's own standard errors underestimate the
    spread (RMS z 1.4, 1.6 and 1.9 over the 30 seeds: neighbouring overlapping estimates are
    correlated; docs/exports.md), so the truth must lie within 4.5 doubled standard errors."""
    truth = {"N": 2e-4, "B": 1.74e-4, "K": 2e-5}
    y = synthetic_rate(N_3H, RATE, white=truth["N"], flicker=truth["B"],
                       random_walk=truth["K"], seed=3)  # fmt: skip
    fit = fit_noise_terms(overlapping_adev(y, RATE), level=LEVEL)
    for term, spread in SPREAD_3H.items():
        t = fit.terms[term]
        assert t.resolved, term
        assert abs(t.value / truth[term] - 1) < 4.5 * spread, (term, t.value)
        assert abs(t.value - truth[term]) < 4.5 * 2 * t.std, (term, t.value, t.std)
    assert not fit.terms["Q"].resolved


def test_a_short_record_bounds_the_random_walk_it_cannot_resolve():
    """10 min of white noise and a weak random walk: K is not resolved, its bound holds it."""
    n, k = int(600 * RATE), 2e-6
    y = synthetic_rate(n, RATE, white=2e-3, flicker=0.0, random_walk=k, seed=5)
    fit = fit_noise_terms(overlapping_adev(y, RATE), level=LEVEL)
    assert fit.terms["N"].resolved and abs(fit.terms["N"].value / 2e-3 - 1) < 0.10
    assert not fit.terms["K"].resolved and fit.terms["K"].value is None
    assert fit.terms["K"].upper_bound > k


@pytest.fixture(scope="module")
def simulated_static(tmp_path_factory):
    """A simulated 3 h static with white noise and bias random walk only (no Gauss-Markov).

    The random walks are five times the simulator's realistic default (acc 1e-4 m/s^2/sqrt(s),
    gyr 1e-5 rad/s/sqrt(s)) so that K dominates from about 30 s on, seven octaves of a 3 h
    record; at the default it takes over only at 130-170 s and the last four octaves (a few
    degrees of freedom each) leave K uncertain to some 20 %.
    """
    from imucal.io import read_imu_csv
    from imucal.sim import parse_effect, simulate

    out = tmp_path_factory.mktemp("sim3h")
    effect = parse_effect(
        "bias_instability:acc_rw=1e-4,gyr_rw=1e-5,acc_gm=0,gyr_gm=0,mag_rw=0,mag_gm=0"
    )
    session = simulate(out, preset="paper", seed=3, effects=(effect,), static_s=10800.0)
    return read_imu_csv(out / "static.csv"), session, out


def test_simulated_three_hour_static_recovers_n_and_k(simulated_static):
    """The simulator's white noise (N = std / sqrt(f_s), plus the rounding to counts, whose
    variance step^2 / 12 adds to it) and its bias random walk (K = *_rw) per axis: N within
    10 %, K within 25 %. Its bias instability is a Gauss-Markov process, not flicker noise,
    so it has no IEEE B to compare with: B is checked on the synthetic series above."""
    import json

    table, session, folder = simulated_static
    truth = json.loads((folder / "truth.json").read_text())
    sens = session.sensitivity
    rw = truth["effects"]["bias_instability"]
    columns = {TIME: table[TIME].to_numpy(dtype=float)}
    for sensor, names in (("acc", ACC), ("gyr", GYR)):
        for name in names:
            columns[name] = table[name].to_numpy(dtype=float) * sens[sensor]
    noise = characterise_noise(columns.__getitem__, list(columns), recording="static",
                               window_s=None, min_duration_s=30.0, level=LEVEL)  # fmt: skip
    for sensor in ("acc", "gyr"):
        white = np.sqrt((truth["noise"][sensor] ** 2 + sens[sensor] ** 2 / 12) / RATE)
        for axis, fit in noise["sensors"][sensor]["axes"].items():
            n_fit, k_fit = fit["terms"]["N"], fit["terms"]["K"]
            assert n_fit["resolved"] and abs(n_fit["value"] / white - 1) < 0.10, (sensor, axis)
            k = rw[f"{sensor}_rw"]
            assert k_fit["resolved"] and abs(k_fit["value"] / k - 1) < 0.25, (sensor, axis, k_fit)
    value, resolved = sensor_noise(noise, "gyr", "N")
    assert resolved and value == max(a["terms"]["N"]["value"]
                                     for a in noise["sensors"]["gyr"]["axes"].values())  # fmt: skip


def _columns(n, seed=0):
    rng = np.random.default_rng(seed)
    cols = {TIME: np.arange(n) / RATE}
    for name in ACC + GYR:
        cols[name] = rng.standard_normal(n)
    return cols


def test_a_too_short_recording_is_refused_with_its_span():
    cols = _columns(1000)
    with pytest.raises(ValueError, match=r"spans 10\.0 s .* at least 30\.0 s"):
        characterise_noise(cols.__getitem__, list(cols), recording="static", window_s=None,
                           min_duration_s=30.0, level=LEVEL)  # fmt: skip


def test_window_missing_samples_and_a_slower_sensor():
    """The window selects its span; a sensor sampled on every 10th row is analysed at its own
    rate; one with a hole in one axis only is skipped with the reason."""
    cols = _columns(20_000)
    cols["gyr_y"][5000] = np.nan
    for name in ACC:
        slow = np.full(20_000, np.nan)
        slow[::10] = cols[name][::10]
        cols[name] = slow
    noise = characterise_noise(cols.__getitem__, list(cols), recording="static",
                               window_s=(10.0, 110.0), min_duration_s=30.0, level=LEVEL)  # fmt: skip
    assert noise["n_samples"] == 10_001
    assert list(noise["sensors"]) == ["acc"] and "gyr_y" in noise["skipped"]["gyr"]
    assert noise["sensors"]["acc"]["rate_hz"] == pytest.approx(RATE / 10)
    assert noise["rate_hz"] == pytest.approx(RATE / 10)
    # unit white noise at 10 Hz: N = 1 / sqrt(10 Hz)
    n_x = noise["sensors"]["acc"]["axes"]["x"]["terms"]["N"]["value"]
    assert abs(n_x * np.sqrt(RATE / 10) - 1) < 0.10
    both = characterise_noise(cols.__getitem__, list(cols), recording="static",
                              window_s=(60.0, 190.0), min_duration_s=30.0, level=LEVEL)  # fmt: skip
    assert set(both["sensors"]) == {"acc", "gyr"} and both["rate_hz"] == pytest.approx(RATE)
