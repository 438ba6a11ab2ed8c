"""Gyroscope: bias (eqs. 34-35), scale without tools (eq. 36), rate table (eq. 33)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import z_limit
from scipy.spatial.transform import Rotation

from imucal import errormodel
from imucal.columns import ACC, AXES, GYR, TIME
from imucal.fits.accelerometer import fit_cube
from imucal.fits.gyroscope import (
    estimate_bias,
    estimate_scale,
    make_calibration,
    measure_angle_change,
    pause_mean_weights,
)
from imucal.fits.ratetable import fit_rate_table, fit_rate_table_magnitude, rate_table_crlb
from imucal.io.dataset import read_dataset
from imucal.segments.ratetable import segment_ratetable
from imucal.sim.protocol import CUBE_UP_B

CONFORMANCE = (
    Path(__file__).resolve().parents[2].parent / "shared" / "data" / "conformance" / "clean"
)
NOISE = 0.0015  # rad/s per axis and sample
BIAS = np.array([-0.0735, -0.0165, 0.0014])
RATES_DPS = np.arange(-400, 401, 100)


def gyro_truth() -> np.ndarray:
    return errormodel.compose([1.16, 1.15, 1.145], [0.007, -0.004, -0.005], [0.006, -0.024, -0.024])


def table_rates() -> np.ndarray:
    """True rate vectors (27, 3) in rad/s: 9 rates about x, y, z of B."""
    return np.vstack([np.outer(np.radians(RATES_DPS), e) for e in np.eye(3)])


# ------------------------------------------------------------------------------------------------
# Bias
# ------------------------------------------------------------------------------------------------


def test_bias_ls_slope_and_mean_recover_bias(z_bound):
    rng = np.random.default_rng(10)
    static = BIAS + NOISE * rng.standard_normal((36000, 3))
    est = estimate_bias(static)
    z = z_bound(6)  # two estimates of three axes, 1e-4 over the six
    assert np.all(np.abs(est.bias_ls_rad_s - BIAS) < z * est.std_ls_rad_s)
    assert np.all(np.abs(est.bias_mean_rad_s - BIAS) < z * est.std_mean_rad_s)
    # noise from first differences: 36000 samples give a relative scatter of ~0.5 %
    assert np.allclose(est.noise_std_rad_s, NOISE, rtol=0.03)
    assert est.n_samples == 36000 and est.n_segments == 1


def test_bias_ls_slope_std_matches_closed_form_and_simulation(rms_z_band):
    n = 2000
    # independent closed form: slope weights C_k = 6 (n-k+1)(k-1) / (n (n^2-1)), k = 1..n
    k = np.arange(1, n + 1)
    weights = 6.0 * (n - k + 1) * (k - 1) / (n * (n**2 - 1))
    expected_ratio = np.sqrt(n * np.sum(weights**2))  # std(slope) / std(mean), -> sqrt(1.2)
    rng = np.random.default_rng(11)
    runs = [estimate_bias(BIAS + NOISE * rng.standard_normal((n, 3))) for _ in range(300)]
    ratio = runs[0].std_ls_rad_s / runs[0].std_mean_rad_s
    assert np.allclose(ratio, expected_ratio, rtol=1e-9)
    assert abs(expected_ratio - np.sqrt(1.2)) < 1e-3
    # 900 slopes (300 runs x 3 axes) over their own reported std: RMS z in the chi-square band
    z = (np.array([r.bias_ls_rad_s for r in runs]) - BIAS) / [r.std_ls_rad_s for r in runs]
    low, high = rms_z_band(z.size)
    assert low < np.sqrt(np.mean(z**2)) < high


def test_bias_from_several_static_pauses(z_bound):
    rng = np.random.default_rng(12)
    pauses = [BIAS + NOISE * rng.standard_normal((n, 3)) for n in (150, 300, 220, 180)]
    est = estimate_bias(pauses)
    assert est.n_segments == 4 and est.n_samples == 850
    z = z_bound(9)  # three estimates of three axes
    assert np.all(np.abs(est.bias_ls_rad_s - BIAS) < z * est.std_ls_rad_s)
    assert np.all(np.abs(est.bias_mean_rad_s - BIAS) < z * est.std_mean_rad_s)
    # separate intercepts per pause: a step of the cumulative sum between pauses is harmless,
    # so the slope of a single pause equals that pause's own estimate
    single = estimate_bias(pauses[:1])
    assert np.all(np.abs(single.bias_ls_rad_s - BIAS) < z * single.std_ls_rad_s)


def test_bias_refuses_short_or_non_finite_data():
    with pytest.raises(ValueError, match=r"segment 1: 5 samples, need at least 10"):
        estimate_bias([np.zeros((50, 3)), np.zeros((5, 3))])
    bad = np.zeros((50, 3))
    bad[7, 2] = np.nan
    with pytest.raises(ValueError, match=r"segment 0: 1 of 50 .* not finite"):
        estimate_bias(bad)


# ------------------------------------------------------------------------------------------------
# Rate table
# ------------------------------------------------------------------------------------------------


def simulate_table(rng, matrix=None, n=700):
    matrix = gyro_truth() if matrix is None else matrix
    rates = table_rates()
    counts = np.full(len(rates), n)
    means = errormodel.invert(matrix, BIAS, rates) + NOISE / np.sqrt(n) * rng.standard_normal(
        rates.shape
    )
    return matrix, rates, counts, means


def test_rate_table_recovers_full_matrix_and_bias(z_bound):
    matrix, rates, counts, means = simulate_table(np.random.default_rng(20))
    z = z_bound(18)  # K and b (12), U (6)
    fit = fit_rate_table(means, rates, counts, noise_std_rad_s=np.full(3, NOISE))
    crlb = np.sqrt(np.diag(rate_table_crlb(matrix, rates, counts, np.full(3, NOISE))))
    err = np.concatenate([(fit.matrix - matrix).ravel(), fit.bias - BIAS])
    assert np.all(np.abs(err) < z * crlb), (err / crlb).round(2)
    # with the noise given, the fit's covariance is the bound (evaluated at the estimate)
    assert np.allclose(np.concatenate([fit.std_matrix.ravel(), fit.std_bias]), crlb, rtol=1e-3)
    _rotation, upper = errormodel.upper_triangular_factor(matrix)
    assert np.all(np.abs(fit.upper - upper) < z * fit.std_upper + 1e-12)
    assert np.allclose(fit.rotation @ fit.upper, fit.matrix)
    # magnitude errors (Fig. 15): scale ~1.15 -> ~13 % of 400 deg/s before, noise level after
    assert np.max(np.abs(fit.magnitude_error_before_rad_s)) > 0.5
    assert np.max(np.abs(fit.magnitude_error_after_rad_s)) < 5 * NOISE / np.sqrt(700) * 2


def test_rate_table_noise_from_residuals():
    _matrix, rates, counts, means = simulate_table(np.random.default_rng(21))
    fit = fit_rate_table(means, rates, counts)
    assert fit.dof == 23
    # chi-square with 23 dof: the std estimate scatters by 1/sqrt(46) = 15 %; 50 % is > 3 sigma
    assert np.all(np.abs(fit.noise_std_rad_s / NOISE - 1) < 0.5)


def test_rate_table_refuses_runs_about_two_axes():
    _, rates, counts, means = simulate_table(np.random.default_rng(22))
    with pytest.raises(ValueError, match=r"span 2 dimension\(s\)"):
        fit_rate_table(means[:18], rates[:18], counts[:18])


def test_magnitude_only_fit_cannot_observe_cross_terms():
    # noise-free data: whatever the magnitude fit misses is unobservable, not noise
    matrix = gyro_truth()
    rates = table_rates()
    counts = np.full(len(rates), 700)
    means = errormodel.invert(matrix, BIAS, rates)
    _, upper = errormodel.upper_triangular_factor(matrix)
    magnitude = fit_rate_table_magnitude(means, rates, counts, np.full(3, NOISE))
    vector = fit_rate_table(means, rates, counts, noise_std_rad_s=np.full(3, NOISE))
    off = np.triu_indices(3, 1)
    # the true cross terms of S' are ~0.005-0.03; the magnitude fit cannot recover them
    assert np.max(np.abs(magnitude.upper[off] - upper[off])) > 5e-3
    assert np.max(np.abs(vector.upper - upper)) < 1e-9
    # three unobservable directions: the Jacobian has 3 zero singular values (up to rounding)
    sv = magnitude.singular_values
    assert sv[-3] / sv[0] < 1e-6 and sv[-4] / sv[0] > 1e-3


def test_cube_directions_make_the_magnitude_fit_observable():
    """Contrast: the 45-degree cube positions give the same magnitude model full rank."""
    rng = np.random.default_rng(23)
    directions = np.array(CUBE_UP_B, dtype=float)
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    matrix = gyro_truth()
    positions = [
        errormodel.invert(matrix, BIAS, np.tile(3.0 * d, (100, 1)))
        + NOISE * rng.standard_normal((100, 3))
        for d in directions
    ]
    fit = fit_cube(positions, 3.0)
    _, upper = errormodel.upper_triangular_factor(matrix)
    assert np.all(np.abs(fit.upper - upper) < z_limit(6) * fit.std_upper + 1e-12)


# ------------------------------------------------------------------------------------------------
# Scale without tools (eq. 36)
# ------------------------------------------------------------------------------------------------


def simulate_phase(rng, axis_index: int, turns: float, drop_fraction: float):
    """A platform phase: 2 s pause, rotation by ``turns`` about B's axis, 2 s pause.

    Timestamps jitter by +-1 ms around 100 Hz and ``drop_fraction`` of the packets are lost.
    Returns times, raw gyro, calibrated acc and mag (mag only every 10th packet, NaN between).
    """
    t = np.arange(0, 10.0, 0.01) + rng.uniform(-1e-3, 1e-3, 1000)
    mag_row = np.arange(1000) % 10 == 0
    keep = rng.random(1000) >= drop_fraction
    keep[[0, -1]] = True
    t, mag_row = t[keep], mag_row[keep]
    # angle: raised-cosine rate profile between 2 s and 8 s
    u = np.clip((t - 2.0) / 6.0, 0, 1)
    total = 2 * np.pi * turns
    angle = total * (u - np.sin(2 * np.pi * u) / (2 * np.pi))
    rate = np.where((t > 2) & (t < 8), total / 6.0 * (1 - np.cos(2 * np.pi * u)), 0.0)
    axis = np.eye(3)[axis_index]
    body_to_world = Rotation.from_rotvec(angle[:, None] * axis)
    gravity_up = np.array([0.0, 0.0, 9.81])
    field = np.array([0.38, 0.0, -0.925])  # normalised, dipping north
    acc = body_to_world.inv().apply(gravity_up) + 0.02 * rng.standard_normal((len(t), 3))
    mag = body_to_world.inv().apply(field) + 0.003 * rng.standard_normal((len(t), 3))
    mag[~mag_row] = np.nan
    matrix = errormodel.compose([1.16, 1.15, 1.145], [0.0, 0.0, 0.0], [0.006, -0.024, -0.024])
    raw = errormodel.invert(matrix, BIAS, rate[:, None] * axis) + NOISE * rng.standard_normal(
        (len(t), 3)
    )
    return t, raw, acc, mag, matrix


@pytest.mark.parametrize("axis_index, turns", [(0, 2.0), (1, -1.5), (2, 1.25)])
def test_scale_from_phase_with_lost_packets(axis_index, turns):
    axis = "xyz"[axis_index]
    rng = np.random.default_rng(30 + axis_index)
    t, raw, acc, mag, matrix = simulate_phase(rng, axis_index, turns, drop_fraction=0.1)
    rotation = errormodel.rotation_matrix([0.006, -0.024, -0.024])
    aligned = errormodel.apply(rotation, BIAS, raw)  # T_R (w - o), unit scale (alignment first)
    before, during, after = t < 1.9, (t >= 1.9) & (t <= 8.1), t > 8.1
    change_mag = measure_angle_change(mag[before], mag[during], mag[after], axis)
    assert abs(change_mag - 2 * np.pi * turns) < 0.02  # 10-20 mag samples per pause at 0.003
    # angle noise of each pause mean: mag noise / |field projection| (0.38 at worst, phase z)
    # / sqrt(10 samples in a 2 s pause at 10 Hz, fewer with lost packets); two pauses
    pause_angle_std = 0.003 / 0.38 / np.sqrt(10)
    result = estimate_scale(
        t,
        aligned,
        axis,
        change_mag,
        noise_std_rad_s=NOISE,
        angle_std_rad=pause_angle_std * np.sqrt(2),
    )
    true_scale = np.linalg.norm(matrix[:, axis_index])
    assert result.sign_agrees
    assert result.max_gap_s > 0.015  # lost packets are in the window
    # the std covers the gyro white noise and the pause-mean angle noise; the alignment
    # leaves a second-order term (misalignment^2 * scale spread ~ 1e-5)
    assert abs(result.scale - true_scale) < z_limit(1) * result.std + 1e-5, (
        result.scale,
        true_scale,
    )
    # integrating with a constant step N * 0.01 s, as printed, undercounts by the lost 10 %
    constant_dt = abs(change_mag / (aligned[:, axis_index].sum() * 0.01))
    assert abs(constant_dt - true_scale) > 0.05
    if axis != "z":
        change_acc = measure_angle_change(acc[before], acc[during], acc[after], axis)
        assert abs(change_acc - 2 * np.pi * turns) < 0.01  # ~100 acc samples per pause at 0.02
    else:
        with pytest.raises(ValueError, match=r"phase 'z'.*projection .* need >= 0.3"):
            measure_angle_change(acc[before], acc[during], acc[after], axis)


def test_pause_mean_weights_integrate_to_the_change_of_the_mean_angle():
    rng = np.random.default_rng(5)
    t = np.cumsum(rng.uniform(0.008, 0.012, 400))
    rate = np.sin(t) + 0.3 * rng.standard_normal(400)
    angle = np.concatenate([[0.0], np.cumsum(np.diff(t) * (rate[1:] + rate[:-1]) / 2)])
    before, after = np.array([3, 3, 10, 40, 41]), np.arange(300, 390, 7)
    weights = pause_mean_weights(t, before, after)
    assert weights @ rate == pytest.approx(angle[after].mean() - angle[before].mean(), abs=1e-12)
    # one row each: the trapezoid rule between them
    assert pause_mean_weights(t, [0], [399]) @ rate == pytest.approx(angle[-1], abs=1e-12)
    with pytest.raises(ValueError, match=r"pause after must be 1 or more indices in \[0, 400\)"):
        pause_mean_weights(t, before, [399, 400])


def test_scale_from_a_pause_that_holds_the_end_of_another_turn():
    """The pause before the phase begins while an earlier turn about the same axis (here
    -0.1 rad, 0-1.2 s) still ends: the angle from the pauses' means takes in only part of its
    end, an integral from the pause's first row all of it (the rotation3d z phase after the
    transition about z). Integrated to the change of the mean angle, the scale is within 4 std
    of the truth; over the whole window it is off by 5e-2 rad / 12.6 rad, about 40 std."""
    rng = np.random.default_rng(8)
    t = np.arange(0.0, 12.0, 0.01)
    u = np.clip(t / 1.2, 0, 1)
    v = np.clip((t - 2.0) / 8.0, 0, 1)
    angle = -0.1 * (u - np.sin(2 * np.pi * u) / (2 * np.pi)) + 4 * np.pi * (
        v - np.sin(2 * np.pi * v) / (2 * np.pi)
    )
    rate = np.gradient(angle, t)
    scale = 1.15
    raw = np.zeros((len(t), 3))
    raw[:, 0] = rate / scale + NOISE * rng.standard_normal(len(t))
    field = Rotation.from_rotvec(angle[:, None] * [1.0, 0.0, 0.0]).inv().apply([0.38, 0.0, -0.925])
    field += 0.003 * rng.standard_normal(field.shape)
    window = t >= 0.5  # the pause before begins at 0.5 s, in the earlier turn's end
    mag_row = np.flatnonzero(window & (np.arange(len(t)) % 10 == 0)) - np.argmax(window)
    tw, mag, w = t[window], field[window], raw[window]
    before = mag_row[tw[mag_row] < 2.0]
    after = mag_row[tw[mag_row] >= 10.0]
    during = mag_row[(tw[mag_row] >= 2.0) & (tw[mag_row] < 10.0)]
    change = measure_angle_change(mag[before], mag[during], mag[after], "x")
    angle_std = 0.003 / 0.925 * np.sqrt(1 / len(before) + 1 / len(after))
    weights = pause_mean_weights(tw, before, after)
    result = estimate_scale(
        tw, w, "x", change, noise_std_rad_s=NOISE, angle_std_rad=angle_std, weights=weights
    )
    assert abs(result.scale - scale) < z_limit(1) * result.std, (result.scale, result.std)
    whole = estimate_scale(tw, w, "x", change, noise_std_rad_s=NOISE, angle_std_rad=angle_std)
    assert abs(whole.scale - scale) > 20 * whole.std


def test_scale_refuses_bad_timestamps_and_no_rotation():
    t = np.array([0.0, 0.01, 0.01, 0.03])
    with pytest.raises(ValueError, match=r"not strictly increasing at row 2"):
        estimate_scale(t, np.ones((4, 3)), "x", 1.0)
    with pytest.raises(ValueError, match=r"integrated rate is 0.003 rad"):
        estimate_scale(np.arange(4) * 0.01, np.full((4, 3), 0.1), "y", 1.0)
    with pytest.raises(ValueError, match=r"axis must be one of"):
        estimate_scale(np.arange(4) * 0.01, np.ones((4, 3)), "w", 1.0)
    with pytest.raises(ValueError, match=r"expected t_s \(n,\) and rate_rad_s \(n, 3\)"):
        estimate_scale((np.arange(4) * 0.01)[:, None], np.ones((4, 3)), "x", 1.0)
    with pytest.raises(ValueError, match=r"expected t_s \(n,\) and rate_rad_s \(n, 3\)"):
        estimate_scale(np.arange(4) * 0.01, np.ones((4, 2)), "x", 1.0)


def test_make_calibration():
    cal = make_calibration(BIAS, gyro_truth(), "rate table", std_bias=np.full(3, 1e-5))
    assert cal.unit == "rad/s" and np.allclose(cal.std["bias"], 1e-5)


# ------------------------------------------------------------------------------------------------
# Conformance session
# ------------------------------------------------------------------------------------------------


@pytest.mark.skipif(not CONFORMANCE.is_dir(), reason=f"conformance data absent: {CONFORMANCE}")
def test_conformance_rate_table_matches_truth():
    dataset = read_dataset(CONFORMANCE)
    truth = json.loads((CONFORMANCE / "truth.json").read_text())["gyr"]
    table = pd.read_csv(dataset.recordings["ratetable"])
    acc = table[list(ACC)].to_numpy(float) * dataset.sensitivity["acc"]
    gyr = table[list(GYR)].to_numpy(float) * dataset.sensitivity["gyr"]
    axes, rates_dps = dataset.ratetable["axes"], dataset.ratetable["rates_dps"]
    segments = segment_ratetable(table[TIME].to_numpy(float), acc, gyr, axes, rates_dps)
    assert len(segments) == len(axes) * len(rates_dps), segments
    runs = list(zip(segments["start_index"], segments["end_index"]))
    # the true rate vector of a run: its nominal rate times the unit table axis of B
    axis_unit = np.eye(3)[[AXES.index(a) for a in segments["axis"]]]
    rates = np.radians(segments["rate_dps"].to_numpy(float))[:, None] * axis_unit
    means = np.array([gyr[a:b].mean(axis=0) for a, b in runs])
    counts = np.array([b - a for a, b in runs])
    fit = fit_rate_table(means, rates, counts)
    assert np.max(np.abs(fit.matrix - np.array(truth["matrix"]))) < 2e-3
    assert np.max(np.abs(fit.bias - np.array(truth["bias"]))) < 2e-4
    # and the static recording gives the same bias by both estimators
    static = pd.read_csv(dataset.recordings["static"])[list(GYR)].to_numpy(float)
    est = estimate_bias(static * dataset.sensitivity["gyr"])
    assert np.max(np.abs(est.bias_ls_rad_s - np.array(truth["bias"]))) < 2e-4
    assert np.max(np.abs(est.bias_mean_rad_s - np.array(truth["bias"]))) < 2e-4
