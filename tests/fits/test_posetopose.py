"""Pose-to-pose gyroscope calibration (Tedaldi et al. 2014): recovery of a known truth, refusals."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from imucal import errormodel
from imucal.fits.posetopose import fit_pose_to_pose, gravity_direction_errors

RATE_HZ = 100.0
GYR_NOISE = 0.005  # rad/s per axis and sample
DIR_NOISE = 0.001  # rad per axis, error of a pose's measured gravity direction
BIAS = np.array([0.02, -0.01, 0.005])  # rad/s
UP_WORLD = np.array([0.0, 0.0, 1.0])


def gyro_truth() -> np.ndarray:
    return errormodel.compose([1.05, 0.97, 1.02], [0.01, -0.015, 0.02], [0.02, -0.01, 0.03])


def _cycloid(tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Smooth 0 -> 1 profile and its derivative on tau in [0, 1] (zero rate at both ends)."""
    return tau - np.sin(2 * np.pi * tau) / (2 * np.pi), 1 - np.cos(2 * np.pi * tau)


def make_session(rng, n_poses=25, axes_pool=None, irregular=False, matrix=None):
    """Poses (B -> world) and handling between them: two body-axis turns per interval.

    Returns the measured up directions at each pose (with direction noise) and per interval
    (t_s, raw gyro in rad/s) generated from ``raw = M^-1 omega + bias + noise``.
    """
    matrix = gyro_truth() if matrix is None else matrix
    orientation = Rotation.identity()
    ups = [orientation.apply(UP_WORLD, inverse=True)]
    intervals = []
    t0 = 0.0
    for _ in range(n_poses - 1):
        pieces = []
        for _ in range(2):
            axis = (
                rng.standard_normal(3)
                if axes_pool is None
                else axes_pool[rng.integers(len(axes_pool))]
            )
            axis = axis / np.linalg.norm(axis)
            angle = rng.uniform(0.6, 1.6) * rng.choice([-1, 1])
            pieces.append((axis, angle, rng.uniform(0.8, 1.5)))
        times, rates = [], []
        for axis, angle, duration in pieces:
            n = int(duration * RATE_HZ)
            if irregular:
                steps = rng.uniform(0.4, 1.6, n) / RATE_HZ
                t = np.concatenate([[0.0], np.cumsum(steps)])
                t *= duration / t[-1]
            else:
                t = np.linspace(0.0, duration, n + 1)
            _, ds = _cycloid(t / duration)
            omega = np.outer(angle * ds / duration, axis)  # body rate about a fixed body axis
            times.append(t0 + t)
            rates.append(omega)
            orientation = orientation * Rotation.from_rotvec(angle * axis)
            t0 += duration
        # the two pieces meet at rest (rate 0), so the shared sample is counted once
        t_all = np.concatenate([times[0], times[1][1:]])
        w_all = np.vstack([rates[0], rates[1][1:]])
        raw = errormodel.invert(matrix, BIAS, w_all) + GYR_NOISE * rng.standard_normal(w_all.shape)
        intervals.append((t_all, raw))
        ups.append(orientation.apply(UP_WORLD, inverse=True))
        t0 += 2.0
    ups = np.array(ups) + DIR_NOISE * rng.standard_normal((n_poses, 3))
    return ups / np.linalg.norm(ups, axis=1, keepdims=True), intervals


@pytest.mark.parametrize("irregular", [False, True])
def test_pose_to_pose_recovers_gyro_matrix(irregular):
    rng = np.random.default_rng(11 + irregular)
    ups, intervals = make_session(rng, irregular=irregular)
    fit = fit_pose_to_pose(ups[:-1], ups[1:], intervals, BIAS)
    truth = errormodel.decompose(gyro_truth())
    expected = np.concatenate([truth.scale, truth.xi_rad, truth.alpha_rad])
    err = fit.parameters - expected
    # Noise per residual component: the two direction errors (DIR_NOISE each) and the integrated
    # gyro noise GYR_NOISE * sqrt(T / rate) ~ 7e-4 rad over T ~ 2.5 s: about 1.6e-3 rad. With 24
    # intervals turning ~2 rad each, a parameter is determined to ~1.6e-3 / (2 sqrt(24 / 3))
    # ~ 3e-4; the fit's own std must be of that order (< 1e-3), and the errors within 5 of them.
    assert np.all(fit.parameter_std < 1e-3), fit.parameter_std
    assert np.all(np.abs(err) < 5 * fit.parameter_std), (err / fit.parameter_std).round(2)
    matrix_err = np.abs(fit.calibration.matrix - gyro_truth())
    assert np.all(matrix_err < 5 * fit.calibration.std["matrix"]), matrix_err
    # residual per dof near the injected noise (1.6e-3 rad), not an order larger
    assert 0.5e-3 < fit.residual_std_rad < 3e-3
    # the nominal matrix (identity) misses the 3-5 % scale errors: degrees, not hundredths
    assert np.sqrt(np.mean(fit.angle_errors_before_deg**2)) > 1.0
    assert np.sqrt(np.mean(fit.angle_errors_deg**2)) < 3 * np.degrees(1.6e-3) * np.sqrt(2)


def test_the_bias_uncertainty_enters_the_matrix_covariance():
    rng = np.random.default_rng(21)
    ups, intervals = make_session(rng)
    bias_std = np.array([2e-3, 3e-3, 1e-3])
    fit = fit_pose_to_pose(ups[:-1], ups[1:], intervals, BIAS, bias_std_rad_s=bias_std)
    cov = np.asarray(fit.calibration.covariance)
    # the covariance's matrix-bias block is d vec(K) / d o times the bias's covariance: a bias
    # moved by a small step moves the fitted matrix by that derivative (first order; 10 %)
    to_matrix = cov[3:12, :3] / bias_std**2
    step = np.array([1e-3, -1e-3, 5e-4])
    moved = fit_pose_to_pose(ups[:-1], ups[1:], intervals, BIAS + step)
    change = (moved.calibration.matrix - fit.calibration.matrix).ravel()
    np.testing.assert_allclose(change, to_matrix @ step, atol=0.1 * np.abs(change).max())
    # and the matrix's variance holds that part on top of the fit's own
    alone = fit_pose_to_pose(ups[:-1], ups[1:], intervals, BIAS, bias_std_rad_s=1e-12 * bias_std)
    extra = np.diag(cov)[3:12] - np.diag(np.asarray(alone.calibration.covariance))[3:12]
    np.testing.assert_allclose(extra, (to_matrix**2) @ bias_std**2, rtol=1e-6, atol=1e-15)


def test_gravity_direction_errors_zero_with_true_calibration_and_no_noise():
    rng = np.random.default_rng(3)
    matrix = gyro_truth()
    orientation = Rotation.identity()
    ups, intervals = [orientation.apply(UP_WORLD, inverse=True)], []
    for _ in range(4):
        axis = rng.standard_normal(3)
        axis /= np.linalg.norm(axis)
        t = np.sort(rng.uniform(0, 2.0, 300))  # irregular timestamps
        t = (t - t[0]) / (t[-1] - t[0]) * 2.0
        _, ds = _cycloid(t / 2.0)
        omega = np.outer(1.3 * ds / 2.0, axis)
        intervals.append((t, errormodel.invert(matrix, BIAS, omega)))
        orientation = orientation * Rotation.from_rotvec(1.3 * axis)
        ups.append(orientation.apply(UP_WORLD, inverse=True))
    ups = np.array(ups)
    err = gravity_direction_errors(ups[:-1], ups[1:], intervals, matrix, BIAS)
    # only the integration error remains: trapezoid error dt^3 |f''| / 12 per step, with
    # |f''| <= 1.3 (2 pi / 2 s)^2 / 2 s = 6.4 rad/s^3 and gaps of sorted uniform times up to
    # ~40 ms: <= 3e-5 rad per step, a few e-5 rad in all; 0.01 deg = 1.7e-4 rad
    assert np.all(err < 0.01), err
    # already-calibrated rates with the identity default give the same answer
    calibrated = [(t, errormodel.apply(matrix, BIAS, w)) for t, w in intervals]
    assert np.allclose(gravity_direction_errors(ups[:-1], ups[1:], calibrated), err, atol=1e-9)
    # a 5 % scale error on every axis tilts the carried direction by degrees
    wrong = gravity_direction_errors(ups[:-1], ups[1:], intervals, 1.05 * matrix, BIAS)
    assert np.max(wrong) > 1.0


def test_refuses_too_few_intervals():
    ups, intervals = make_session(np.random.default_rng(4), n_poses=5)
    with pytest.raises(ValueError, match=r"at least 5 intervals.*got 4"):
        fit_pose_to_pose(ups[:-1], ups[1:], intervals, BIAS)


def test_refuses_rotations_about_one_axis_and_names_missing_axes():
    rng = np.random.default_rng(5)
    ups, intervals = make_session(rng, axes_pool=np.array([[1.0, 0.0, 0.0]]), matrix=np.eye(3))
    with pytest.raises(ValueError, match=r"not observable.*near axis '[yz]'"):
        fit_pose_to_pose(ups[:-1], ups[1:], intervals, BIAS)


def test_refuses_rotations_in_one_plane_and_names_the_normal():
    rng = np.random.default_rng(6)
    pool = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]])
    ups, intervals = make_session(rng, axes_pool=pool, matrix=np.eye(3))
    with pytest.raises(ValueError, match=r"not observable.*near axis 'z'"):
        fit_pose_to_pose(ups[:-1], ups[1:], intervals, BIAS)


def test_refuses_bad_timestamps_and_shapes():
    ups, intervals = make_session(np.random.default_rng(7), n_poses=8)
    t, w = intervals[2]
    bad = list(intervals)
    bad[2] = (t[::-1], w)
    with pytest.raises(ValueError, match=r"interval 2: timestamps must increase"):
        fit_pose_to_pose(ups[:-1], ups[1:], bad, BIAS)
    with pytest.raises(ValueError, match=r"start_directions: expected 7 finite directions"):
        fit_pose_to_pose(ups, ups[1:], intervals, BIAS)
