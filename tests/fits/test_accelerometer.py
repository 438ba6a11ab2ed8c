"""Cube fit (eq. 32): recovery of a known truth, refusals, saturation, conformance session."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import z_limit

from imucal import errormodel
from imucal.columns import ACC, GYR, TIME
from imucal.fits.accelerometer import _residual_std, cube_crlb, fit_cube, heldout_errors
from imucal.io.dataset import read_dataset
from imucal.pipeline.stages import cube_calibration, plain
from imucal.plots.inertial import plot_cube_magnitude_errors
from imucal.segments.protocol import segment_cube
from imucal.sim.protocol import CUBE_UP_B

G = 9.81
NOISE = 0.02  # m/s^2 per axis and sample
N_SAMPLES = 600
CONFORMANCE = (
    Path(__file__).resolve().parents[2].parent / "shared" / "data" / "conformance" / "clean"
)

# the simulator's 12 cube positions: 6 faces and 6 at 45 degrees on the V-block (frame B)
DIRECTIONS = np.array(CUBE_UP_B, dtype=float)
DIRECTIONS /= np.linalg.norm(DIRECTIONS, axis=1, keepdims=True)


def make_truth() -> tuple[np.ndarray, np.ndarray]:
    matrix = errormodel.compose([0.98, 1.01, 1.02], [0.01, -0.02, 0.015], [0.01, 0.02, -0.01])
    return matrix, np.array([0.1, -0.2, 0.3])


def make_positions(matrix, bias, rng, directions=DIRECTIONS, n=N_SAMPLES, noise=NOISE):
    """Raw readings (m/s^2) of static positions: invert the calibration of g * direction."""
    return [
        errormodel.invert(matrix, bias, np.tile(G * d, (n, 1)))
        + noise * rng.standard_normal((n, 3))
        for d in directions
    ]


def crlb_std(matrix: np.ndarray) -> np.ndarray:
    """CRLB std of (S' upper entries, o) at the truth, shape (9,)."""
    rotation, upper = errormodel.upper_triangular_factor(matrix)
    directions_u = DIRECTIONS @ rotation  # gravity seen in the frame of S'(a - o)
    cov = cube_crlb(upper, directions_u, np.full(12, N_SAMPLES), np.full(3, NOISE), G)
    return np.sqrt(np.diag(cov))


@pytest.mark.parametrize("method", ["means", "samples"])
def test_cube_fit_recovers_truth_within_noise(method):
    matrix, bias = make_truth()
    _, upper = errormodel.upper_triangular_factor(matrix)
    fit = fit_cube(make_positions(matrix, bias, np.random.default_rng(1)), G, method=method)
    std = crlb_std(matrix)
    err = np.concatenate([(fit.upper - upper)[np.triu_indices(3)], fit.bias - bias])
    # within the CRLB std times the two-sided bound of 9 normal errors at 1e-4 (4.4)
    assert np.all(np.abs(err) < z_limit(9) * std), (err / std).round(2)
    assert np.allclose(np.tril(fit.upper, -1), 0)
    assert fit.dof == (3 if method == "means" else 12 * N_SAMPLES - 9)


def test_cube_fit_covariance_equals_crlb():
    matrix, bias = make_truth()
    fit = fit_cube(make_positions(matrix, bias, np.random.default_rng(2)), G)
    fit_std = np.concatenate([fit.std_upper[np.triu_indices(3)], fit.std_bias])
    # the fit's Jacobian covariance is the bound to first order; the noise estimate from
    # 12 * 599 dof scatters by ~1 %, the evaluation point (estimate vs truth) by less
    assert np.allclose(fit_std, crlb_std(matrix), rtol=0.05)


def test_residual_weights_are_the_noise_of_the_calibrated_norm():
    """The weights of eq. 32 (and of the rate table's magnitude fit) are the noise std of
    ``|U(v - o)|``: ``|diag(noise) U^T n|``, U's columns weighting each axis' noise. Against
    the std of 100000 draws per vector (its sampling error 0.2 %; 1 % allowed) for a
    gyroscope-like U (scales 0.85-1.2, cross terms 0.05-0.1) and unequal noise per axis;
    leaving out U changes it by 2-20 % (5 of the 6 beyond 1 %)."""
    rng = np.random.default_rng(5)
    upper = np.array([[1.2, 0.1, -0.05], [0.0, 0.85, 0.08], [0.0, 0.0, 1.1]])
    bias = np.array([0.02, -0.01, 0.03])
    noise = np.array([0.002, 0.005, 0.003])
    vectors = bias + rng.normal(size=(6, 3))
    counts = np.array([1, 1, 4, 4, 9, 100])
    predicted = _residual_std(upper, bias, vectors, counts, noise)
    for v, c, p in zip(vectors, counts, predicted):
        draws = v + noise * rng.standard_normal((100_000, 3)) / np.sqrt(c)
        sampled = np.std(np.linalg.norm((draws - bias) @ upper.T, axis=1))
        assert p == pytest.approx(sampled, rel=0.01)


def test_cube_magnitude_errors_before_and_after():
    matrix, bias = make_truth()
    fit = fit_cube(make_positions(matrix, bias, np.random.default_rng(3)), G)
    assert fit.magnitude_error_before_m_s2.shape == (12,)
    # the uncalibrated sensor is off by a scale of ~2 % and a bias of 0.3 m/s^2
    assert np.max(np.abs(fit.magnitude_error_before_m_s2)) > 0.15
    # after the fit a position's norm scatters by ~ noise / sqrt(n) = 8e-4 m/s^2
    assert np.max(np.abs(fit.magnitude_error_after_m_s2)) < 5 * NOISE / np.sqrt(N_SAMPLES)
    assert fit.chi2 < 25  # chi2 with 3 dof: P(> 25) ~ 2e-5


def test_cube_figure_shows_the_fit_residuals():
    matrix, bias = make_truth()
    fit = fit_cube(make_positions(matrix, bias, np.random.default_rng(9)), G)
    fig = plot_cube_magnitude_errors(fit)
    _top, bottom = fig.axes
    heights = np.array([bar.get_height() for bar in bottom.patches])
    assert np.allclose(heights, fit.magnitude_error_after_m_s2)
    assert [t.get_text() for t in bottom.get_xticklabels()] == list(fit.labels)


def test_heldout_errors_leave_each_position_out():
    matrix, bias = make_truth()
    positions = make_positions(matrix, bias, np.random.default_rng(4))
    held = heldout_errors(positions, G)
    raw = np.array([np.linalg.norm(p.mean(axis=0)) - G for p in positions])
    assert np.allclose(held.before, raw)
    # a held-out position is off by its own mean's noise through the norm (NOISE / sqrt(n))
    # plus the fit's error at it (3 positions of slack for 9 unknowns: a few times that)
    assert np.all(np.abs(held.after) < 10 * NOISE / np.sqrt(N_SAMPLES))
    # and the predicted std says so: at least the mean's noise, at most the bound above
    assert np.all(held.predicted_std > 0.9 * NOISE / np.sqrt(N_SAMPLES))
    assert np.all(held.predicted_std < 10 * NOISE / np.sqrt(N_SAMPLES))
    # a position pushed off the sphere is seen held out, not absorbed by the fit
    positions[0] = positions[0] * 1.01
    shifted = heldout_errors(positions, G)
    assert shifted.after[0] == pytest.approx(0.01 * G, rel=0.3)
    assert abs(shifted.z[0]) > 10
    with pytest.raises(ValueError, match="at least 10"):
        heldout_errors(positions[:9], G)


def test_heldout_errors_are_as_large_as_their_predicted_std(rms_z_band):
    # over 40 sessions of 12 positions, held-out z = after / predicted_std has unit variance
    # when the covariance is honest: 480 values (12 per session share fits, so fewer are
    # independent, about 40 x 3): the RMS of z within the two-sided band of 120 draws
    matrix, bias = make_truth()
    z = np.concatenate(
        [heldout_errors(make_positions(matrix, bias, np.random.default_rng(100 + k)), G).z
         for k in range(40)]
    )  # fmt: skip
    low, high = rms_z_band(120)
    assert low < np.sqrt(np.mean(z**2)) < high


def test_cube_fit_refuses_fewer_than_nine_positions():
    matrix, bias = make_truth()
    positions = make_positions(matrix, bias, np.random.default_rng(4))[:8]
    with pytest.raises(ValueError, match=r"at least 9 static positions.*uses 12.*found 8"):
        fit_cube(positions, G)


def test_cube_fit_refuses_non_finite_samples():
    matrix, bias = make_truth()
    positions = make_positions(matrix, bias, np.random.default_rng(5))
    positions[3][10, 1] = np.nan
    with pytest.raises(ValueError, match=r"position 'p04': 1 of 600 .* not finite"):
        fit_cube(positions, G)


def test_saturated_samples_are_excluded_with_warning():
    matrix, bias = make_truth()
    limit = 16.0  # m/s^2, the sensor range
    positions = make_positions(matrix, bias, np.random.default_rng(6))
    # a knock while the cube rests on p05: 30 samples clipped at the range on x
    positions[4][100:130, 0] = limit
    clean = fit_cube(positions, G, saturation_limit_m_s2=limit)
    assert clean.n_excluded.tolist() == [0, 0, 0, 0, 30] + [0] * 7
    assert any("'p05': 30 of 600 saturated" in w for w in clean.warnings)
    _, upper = errormodel.upper_triangular_factor(matrix)
    err = np.concatenate([(clean.upper - upper)[np.triu_indices(3)], clean.bias - bias])
    std = crlb_std(matrix)
    assert np.all(np.abs(err) < z_limit(9) * std)
    # the same data without the exclusion: the knock biases the fit far beyond the noise
    polluted = fit_cube(positions, G)
    err_polluted = np.concatenate(
        [(polluted.upper - upper)[np.triu_indices(3)], polluted.bias - bias]
    )
    assert np.max(np.abs(err_polluted) / std) > 20


def test_saturated_position_dropped_then_too_few_refused():
    matrix, bias = make_truth()
    positions = make_positions(matrix, bias, np.random.default_rng(7))
    masks = [np.zeros(N_SAMPLES, dtype=bool) for _ in positions]
    masks[0][:] = True  # p01 is clipped throughout
    fit = fit_cube(positions, G, saturated=masks)
    assert fit.labels[0] == "p02" and len(fit.labels) == 11
    assert any("'p01' dropped" in w for w in fit.warnings)
    with pytest.raises(ValueError, match=r"found 8 usable of 9.*'p01' dropped"):
        fit_cube(positions[:9], G, saturated=masks[:9])


def test_cube_calibration_carries_the_covariance_and_inflates_by_the_chi_square():
    matrix, bias = make_truth()
    rotation, upper = errormodel.upper_triangular_factor(matrix)
    fit = fit_cube(make_positions(matrix, bias, np.random.default_rng(8)), G)
    cal = cube_calibration(plain(fit))
    # white noise: chi-square below its 0.999 quantile, the std are the fit's own
    assert cal.quality["cube"]["inflation"] == 1.0
    np.testing.assert_allclose(cal.std["matrix"], fit.std_upper, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(cal.std["bias"], fit.std_bias, rtol=1e-9)
    assert np.max(np.abs(cal.matrix - upper)) < z_limit(6) * crlb_std(matrix)[:6].max()
    # a placement error per position (0.02 m/s^2, ten times the noise of a mean) scatters the
    # positions beyond the noise: the covariance grows by chi2 / dof
    rng = np.random.default_rng(9)
    moved = [p + 0.02 * rng.standard_normal(3) for p in make_positions(matrix, bias, rng)]
    scattered = fit_cube(moved, G)
    inflated = cube_calibration(plain(scattered))
    ratio = scattered.chi2 / scattered.dof
    assert inflated.quality["cube"]["inflation"] == pytest.approx(ratio) and ratio > 5
    np.testing.assert_allclose(inflated.std["bias"], np.sqrt(ratio) * scattered.std_bias, rtol=1e-9)


# ------------------------------------------------------------------------------------------------
# Conformance session (independent generator, truth.json)
# ------------------------------------------------------------------------------------------------


@pytest.mark.skipif(not CONFORMANCE.is_dir(), reason=f"conformance data absent: {CONFORMANCE}")
def test_conformance_cube_fit_matches_truth():
    dataset = read_dataset(CONFORMANCE)
    truth = json.loads((CONFORMANCE / "truth.json").read_text())["acc"]
    table = pd.read_csv(dataset.recordings["cube"])
    acc = table[list(ACC)].to_numpy(float) * dataset.sensitivity["acc"]
    gyr = table[list(GYR)].to_numpy(float) * dataset.sensitivity["gyr"]
    segments = segment_cube(table[TIME].to_numpy(float), acc, gyr)
    positions = segments[segments["kind"] == "position"]
    assert len(positions) == 12, positions
    windows = list(zip(positions["start_index"], positions["end_index"]))
    fit = fit_cube(
        [acc[a:b] for a, b in windows],
        dataset.gravity_m_s2,
        saturation_limit_m_s2=dataset.range_counts["acc"] * dataset.sensitivity["acc"],
    )
    _, upper_true = errormodel.upper_triangular_factor(np.array(truth["matrix"]))
    assert np.max(np.abs(fit.upper - upper_true)) < 2e-3
    assert np.max(np.abs(fit.bias - np.array(truth["bias"]))) < 0.01
    assert fit.warnings == ()
    # the residual norms scatter like the noise (chi2 with 3 dof: P(> 25) ~ 2e-5)
    assert fit.chi2 < 25


def test_a_given_sample_noise_weights_the_fit_as_the_pooled_one_does():
    """The noise per axis, given (known from a static recording) instead of pooled from the
    positions' scatter: the fit uses it as given, and at the pooled value it is the same fit."""
    matrix, bias = make_truth()
    positions = make_positions(matrix, bias, np.random.default_rng(4))
    pooled = fit_cube(positions, G)
    given = fit_cube(positions, G, noise_std_m_s2=pooled.noise_std_m_s2)
    np.testing.assert_allclose(given.noise_std_m_s2, pooled.noise_std_m_s2)
    np.testing.assert_allclose(given.upper, pooled.upper, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(given.std_bias, pooled.std_bias, rtol=1e-9)
    # a tenfold noise gives tenfold stds (the weights' scale is not refitted)
    tenfold = fit_cube(positions, G, noise_std_m_s2=10 * pooled.noise_std_m_s2)
    np.testing.assert_allclose(tenfold.std_bias, 10 * pooled.std_bias, rtol=1e-6)
