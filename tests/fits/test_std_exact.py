"""The standard deviations the fits report, rebuilt here from their residuals and designs.

A multi-seed RMS-z check sees a wrong factor only when it is large (a std off by 6 % moves the
RMS z of 200 sessions by less than its band); these tests see it exactly. Each rebuilds the
reported std from the residuals the fit leaves (variance over the degrees of freedom, the
sqrt, the design's inverse normal matrix) by an independent route, or compares a fit with the
same fit of its data given twice: the solution and the residual variance stay, the normal
matrix doubles, the degrees of freedom go from ``N - p`` to ``2 N - p``, so the std moves by
exactly ``sqrt((N - p) / (2 N - p))``; a wrong dof, a missing sqrt or a missing factor moves
that ratio.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from imucal import errormodel
from imucal.fits.accelerometer import fit_cube
from imucal.fits.ferraris import fit_known_orientations
from imucal.fits.gyroscope import BIAS_BLOCK_SAMPLES, estimate_bias
from imucal.fits.posetopose import fit_pose_to_pose
from imucal.fits.ratetable import fit_rate_table
from imucal.fits.reference import WINDOW_S, fit_gyro_to_reference

G = 9.81


def _cube_directions() -> np.ndarray:
    faces = np.vstack([np.eye(3), -np.eye(3)])
    tilted = np.array([[1, 1, 0], [-1, 1, 0], [0, 1, 1], [0, -1, 1], [1, 0, 1], [1, 0, -1]])
    d = np.vstack([faces, tilted]).astype(float)
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def _acc_truth() -> tuple[np.ndarray, np.ndarray]:
    matrix = errormodel.compose([0.98, 1.01, 1.02], [0.01, -0.02, 0.015], [0.01, 0.02, -0.01])
    return matrix, np.array([0.1, -0.2, 0.3])


def test_cube_fit_noise_and_covariance_from_its_residuals():
    """Eq. 32 fitted to the means: the noise is the pooled within-position std (each position
    loses one dof to its mean), the covariance the inverse normal matrix of the residuals
    weighted by the noise of ``|U (m - o)|``: ``|diag(noise) U^T n| / sqrt(n_i)``."""
    rng = np.random.default_rng(41)
    matrix, bias = _acc_truth()
    d = _cube_directions()
    counts = [40, 25, 60, 33, 48, 20, 55, 41, 30, 62, 27, 36]  # unequal: the dof per position
    noise = np.array([0.02, 0.035, 0.05])
    positions = [
        errormodel.invert(matrix, bias, np.tile(G * di, (c, 1)))
        + noise * rng.standard_normal((c, 3))
        for di, c in zip(d, counts)
    ]
    fit = fit_cube(positions, G)
    pooled = np.sqrt(
        sum(((p - p.mean(axis=0)) ** 2).sum(axis=0) for p in positions) / (sum(counts) - 12)
    )
    np.testing.assert_allclose(fit.noise_std_m_s2, pooled, rtol=1e-12)

    means = np.array([p.mean(axis=0) for p in positions])
    n_i = np.array(counts, dtype=float)

    def residuals(theta: np.ndarray, upper_w: np.ndarray, bias_w: np.ndarray) -> np.ndarray:
        upper = np.zeros((3, 3))
        upper[np.triu_indices(3)] = theta[:6]
        scaled_w = (means - bias_w) @ upper_w.T
        direction = scaled_w / np.linalg.norm(scaled_w, axis=1, keepdims=True)
        sigma = np.linalg.norm((direction @ upper_w) * fit.noise_std_m_s2, axis=1) / np.sqrt(n_i)
        return (np.linalg.norm((means - theta[6:]) @ upper.T, axis=1) - G) / sigma

    theta = np.r_[fit.upper[np.triu_indices(3)], fit.bias]
    jac = np.empty((12, 9))
    for k in range(9):
        dp = np.zeros(9)
        dp[k] = 1e-7
        jac[:, k] = (
            residuals(theta + dp, fit.upper, fit.bias) - residuals(theta - dp, fit.upper, fit.bias)
        ) / 2e-7
    want = np.linalg.inv(jac.T @ jac)
    # the fit weights with the solution of its previous iteration: equal to ~1e-6
    np.testing.assert_allclose(fit.covariance, want, rtol=1e-4, atol=1e-12 * np.abs(want).max())
    np.testing.assert_allclose(fit.std_bias, np.sqrt(np.diag(want)[6:]), rtol=1e-4)
    assert fit.chi2 == pytest.approx(
        float(np.sum(residuals(theta, fit.upper, fit.bias) ** 2)), rel=1e-4
    )
    assert fit.dof == 12 - 9


def _table(rng, n_runs=18):
    matrix = errormodel.compose([1.05, 0.97, 1.1], [0.01, -0.02, 0.015], [0.02, 0.01, -0.03])
    bias = np.array([0.01, -0.02, 0.005])
    axes = np.vstack([np.eye(3), -np.eye(3), _cube_directions()[6:]])
    rates = np.vstack([a * s for a in axes for s in (1.0, 3.0)])[:n_runs] * [1.0, 1.0, 1.0]
    counts = rng.integers(200, 900, n_runs)
    noise = np.array([0.004, 0.006, 0.009])
    means = errormodel.invert(matrix, bias, rates) + noise / np.sqrt(counts)[:, None] * (
        rng.standard_normal(rates.shape)
    )
    return rates, counts, means


def test_rate_table_noise_and_std_from_its_weighted_residuals():
    """Eq. 33 (vector form): per sensor axis a weighted regression of the run means on
    ``(rate, 1)``; the noise is ``sqrt(sum n r^2 / (N - 4))`` and the covariance of ``(K^-1,
    b)`` that noise squared times ``(X^T N X)^-1``, carried to ``K`` through ``dK = -K dA K``."""
    rates, counts, means = _table(np.random.default_rng(42))
    fit = fit_rate_table(means, rates, counts)
    x = np.column_stack([rates, np.ones(len(rates))])
    sw = np.sqrt(counts)[:, None]
    coef, *_ = np.linalg.lstsq(x * sw, means * sw, rcond=None)
    resid = means - x @ coef
    noise = np.sqrt(np.sum(counts[:, None] * resid**2, axis=0) / (len(rates) - 4))
    np.testing.assert_allclose(fit.noise_std_rad_s, noise, rtol=1e-10)
    gram_inv = np.linalg.inv((x * counts[:, None]).T @ x)
    np.testing.assert_allclose(fit.std_bias, noise * np.sqrt(gram_inv[3, 3]), rtol=1e-10)
    # K = A^-1 by central differences of the inverse, row k of A with noise_k^2 gram_inv
    a = coef[:3].T
    jac = np.empty((9, 9))
    for i in range(9):
        da = np.zeros(9)
        da[i] = 1e-7
        jac[:, i] = (
            np.linalg.inv(a + da.reshape(3, 3)) - np.linalg.inv(a - da.reshape(3, 3))
        ).ravel() / 2e-7
    cov_a = np.zeros((9, 9))
    for k in range(3):
        cov_a[3 * k : 3 * k + 3, 3 * k : 3 * k + 3] = noise[k] ** 2 * gram_inv[:3, :3]
    want = np.sqrt(np.diag(jac @ cov_a @ jac.T)).reshape(3, 3)
    np.testing.assert_allclose(fit.std_matrix, want, rtol=1e-5)
    assert fit.dof == len(rates) - 4


def test_rate_table_std_of_the_upper_factor_is_carried_through_the_qr():
    """``std_upper``: the matrix covariance carried through ``K -> (R, U)`` by central
    differences here, against the fit's."""
    rates, counts, means = _table(np.random.default_rng(43))
    fit = fit_rate_table(means, rates, counts)
    jac = np.empty((9, 9))
    for i in range(9):
        dk = np.zeros(9)
        dk[i] = 1e-7
        plus = errormodel.upper_triangular_factor(fit.matrix + dk.reshape(3, 3))[1]
        minus = errormodel.upper_triangular_factor(fit.matrix - dk.reshape(3, 3))[1]
        jac[:, i] = (plus - minus).ravel() / 2e-7
    want = np.sqrt(np.clip(np.diag(jac @ fit.covariance[:9, :9] @ jac.T), 0, None)).reshape(3, 3)
    np.testing.assert_allclose(fit.std_upper, want, rtol=1e-4, atol=1e-12)


def test_bias_noise_mean_and_slope_std_from_the_samples():
    """The gyro bias: the white noise from first differences (``sum d^2 / (2 (n - 1))`` per
    segment pooled), the mean's std ``noise / sqrt(n)``, the slope's (eq. 35)
    ``noise sqrt(sum C_k^2)`` with the common-slope weights of several segments, and the
    block chi-square and its dof."""
    rng = np.random.default_rng(44)
    sizes = (1500, 900)
    segments = [np.array([0.01, -0.02, 0.03]) + [0.002, 0.003, 0.005] * rng.standard_normal((n, 3))
                for n in sizes]  # fmt: skip
    fit = estimate_bias(segments)
    diff_ss = sum(np.sum(np.diff(s, axis=0) ** 2, axis=0) for s in segments)
    noise = np.sqrt(diff_ss / (2 * (sum(sizes) - len(sizes))))
    np.testing.assert_allclose(fit.noise_std_rad_s, noise, rtol=1e-12)
    np.testing.assert_allclose(fit.std_mean_rad_s, noise / np.sqrt(sum(sizes)), rtol=1e-12)
    # slope weights: b = sum_k C_k w_k, C_k the sum over i >= k of (i - mean(i)) / S_xx
    sxx = sum(np.sum((np.arange(n) - (n - 1) / 2) ** 2) for n in sizes)
    weights = np.concatenate(
        [np.cumsum(((np.arange(n) - (n - 1) / 2) / sxx)[::-1])[::-1] for n in sizes]
    )
    np.testing.assert_allclose(fit.std_ls_rad_s, noise * np.sqrt(np.sum(weights**2)), rtol=1e-10)
    np.testing.assert_allclose(
        fit.bias_ls_rad_s, weights @ np.vstack(segments), rtol=1e-9, atol=1e-12
    )
    blocks = [b for s in segments for b in np.array_split(s, max(1, len(s) // BIAS_BLOCK_SAMPLES))]
    assert fit.dof_blocks == len(blocks) - 1
    means = np.array([b.mean(axis=0) for b in blocks])
    n_b = np.array([len(b) for b in blocks])[:, None]
    chi2 = np.sum(n_b * (means - np.vstack(segments).mean(axis=0)) ** 2, axis=0) / noise**2
    np.testing.assert_allclose(fit.chi2_blocks, chi2, rtol=1e-10)


def test_known_orientation_std_from_the_residual_variance_over_3_n_minus_12():
    """Ferraris's six faces and more, equal weights: one regression of the position means on
    ``(g d, 1)`` per axis, the residual variance pooled over the three axes with ``3 (n - 4)``
    dof; the bias std is its square root times ``sqrt((X^T X)^-1)[3, 3]``."""
    rng = np.random.default_rng(45)
    matrix, bias = _acc_truth()
    d = _cube_directions()
    positions = [
        errormodel.invert(matrix, bias, np.tile(G * di, (50, 1)))
        + 0.02 * rng.standard_normal((50, 3)) + 0.01 * rng.standard_normal(3)
        for di in d
    ]  # fmt: skip
    fit = fit_known_orientations(positions, d, G, weighting="equal")
    means = np.array([p.mean(axis=0) for p in positions])
    x = np.column_stack([G * d, np.ones(len(d))])
    coef, *_ = np.linalg.lstsq(x, means, rcond=None)
    s2 = np.sum((means - x @ coef) ** 2) / (3 * (len(d) - 4))
    assert fit.dof == 3 * (len(d) - 4)
    assert fit.residual_std_m_s2 == pytest.approx(np.sqrt(s2), rel=1e-10)
    xtx_inv = np.linalg.inv(x.T @ x)
    np.testing.assert_allclose(fit.calibration.std["bias"], np.sqrt(s2 * xtx_inv[3, 3]), rtol=1e-8)


def _pose_session(rng, n_poses=9):
    """Up directions at ``n_poses`` poses and the raw gyroscope between them (two turns each)."""
    matrix = errormodel.compose([1.05, 0.97, 1.02], [0.01, -0.015, 0.02], [0.02, -0.01, 0.03])
    bias = np.array([0.02, -0.01, 0.005])
    orientation = Rotation.identity()
    ups = [orientation.apply([0, 0, 1.0], inverse=True)]
    intervals = []
    for _ in range(n_poses - 1):
        axis = rng.standard_normal(3)
        axis /= np.linalg.norm(axis)
        angle = rng.uniform(0.8, 1.6) * rng.choice([-1, 1])
        t = np.linspace(0.0, 1.5, 151)
        rate = np.outer(angle / 1.5 * (1 - np.cos(2 * np.pi * t / 1.5)), axis)
        raw = errormodel.invert(matrix, bias, rate) + 0.005 * rng.standard_normal(rate.shape)
        intervals.append((t, raw))
        orientation = orientation * Rotation.from_rotvec(angle * axis)
        ups.append(orientation.apply([0, 0, 1.0], inverse=True))
    ups = np.array(ups) + 0.002 * rng.standard_normal((n_poses, 3))
    return ups / np.linalg.norm(ups, axis=1, keepdims=True), intervals, bias


def test_pose_to_pose_std_over_2_n_minus_9_dof():
    """``s^2 (J^T J)^-1`` with ``s^2 = RSS / (2 n - 9)``: the same intervals given twice keep
    the solution and the RSS per interval, double ``J^T J`` and give ``4 n - 9`` dof."""
    ups, intervals, bias = _pose_session(np.random.default_rng(46))
    n = len(intervals)
    once = fit_pose_to_pose(ups[:-1], ups[1:], intervals, bias)
    twice = fit_pose_to_pose(
        np.vstack([ups[:-1]] * 2), np.vstack([ups[1:]] * 2), intervals * 2, bias
    )
    assert (once.dof, twice.dof) == (2 * n - 9, 4 * n - 9)
    np.testing.assert_allclose(twice.parameters, once.parameters, atol=1e-7)
    ratio = np.sqrt((2 * n - 9) / (4 * n - 9))
    np.testing.assert_allclose(twice.parameter_std / once.parameter_std, ratio, rtol=2e-3)
    # the residual std is that of one residual: RSS / dof
    assert twice.residual_std_rad / once.residual_std_rad == pytest.approx(
        np.sqrt(2 * (2 * n - 9) / (4 * n - 9)), rel=2e-3
    )


def test_pose_to_pose_matrix_covariance_is_carried_from_scale_xi_alpha():
    """The matrix entries' covariance ``J C J^T`` (``J`` of eq. 1's composition): carried back
    to (scale, xi, alpha) by the decomposition it must give their own std again (the
    composition's Jacobian is not symmetric, so ``J^T C J`` does not), with a bias of zero std
    and without one."""
    from imucal import uncertainty

    ups, intervals, bias = _pose_session(np.random.default_rng(46))
    plain = fit_pose_to_pose(ups[:-1], ups[1:], intervals, bias)
    joint = fit_pose_to_pose(ups[:-1], ups[1:], intervals, bias, bias_std_rad_s=np.zeros(3))
    std = uncertainty.std_of(joint.calibration.covariance)
    back = np.concatenate([std["scale"], std["xi_rad"], std["alpha_rad"]])
    np.testing.assert_allclose(back, plain.parameter_std, rtol=1e-4)
    np.testing.assert_allclose(std["matrix"], plain.calibration.std["matrix"], rtol=1e-6)


def _reference_recording(duration_s=120.0, ref_hz=100.0, imu_hz=200.0):
    t = np.arange(0.0, duration_s, 1 / imu_hz)
    omega = np.column_stack([np.sin(0.9 * t), np.cos(0.7 * t + 0.3), 0.8 * np.sin(0.5 * t + 1.0)])
    from imucal.orientation import integrate_rates

    q = integrate_rates(t, omega)
    tau = np.arange(0.0, duration_s, 1 / ref_hz)
    from imucal.orientation import interpolate_orientation

    return t, omega, tau, interpolate_orientation(t, q, tau)


def test_reference_windows_are_disjoint_and_each_spans_the_window():
    """Consecutive windows share no reference sample (the reference's noise at a window end
    enters one window), each spans at least ``WINDOW_S`` and ends at the first sample that
    does: a 120 s recording at 100 Hz with 1 s windows gives windows of 101 samples, 100 + 1
    apart, 118 of them (the last must end before the recording does)."""
    from imucal.fits.reference import _windows

    t, omega, tau, quat = _reference_recording()
    w = _windows(t, omega, tau, quat, WINDOW_S)
    assert np.all(w.a[1:] > w.b[:-1])
    np.testing.assert_allclose(w.b - w.a, 1.0, atol=1e-9)
    np.testing.assert_allclose(np.diff(w.a), 1.01, atol=1e-9)
    assert w.a.size == 118
    fit = fit_gyro_to_reference([(t, omega, tau, quat)], np.eye(3), np.zeros(3))
    assert (fit.n_windows, fit.n_outliers) == (118, 0)


def test_reference_covariance_is_the_formal_and_the_delete_a_block_jackknife():
    """On a linear model with residuals orthogonal to the design (the least-squares solution
    is the truth, the residuals are ``r``): the formal covariance ``r.r / (3 k - p) (J^T
    J)^-1`` and the jackknife of the refits with each of the ``N_BLOCKS`` contiguous blocks of
    windows left out, ``(B - 1) / B sum (d_b - mean d)(d_b - mean d)^T``, here by refitting."""
    from imucal.fits.reference import N_BLOCKS, _covariance

    rng = np.random.default_rng(47)
    k, p = 60, 12
    jac = rng.standard_normal((k, 3, p))
    a = jac.reshape(-1, p)
    r = rng.standard_normal(3 * k) * np.repeat([0.5, 1.0, 2.0], k)
    r -= a @ np.linalg.lstsq(a, r, rcond=None)[0]  # orthogonal to the design
    free = np.ones(p, dtype=bool)
    free[4] = False  # a held entry
    formal, jack = _covariance(r.reshape(k, 3), jac, free)
    af = a[:, free]
    np.testing.assert_allclose(
        formal, r @ r / (3 * k - free.sum()) * np.linalg.inv(af.T @ af), rtol=1e-9
    )
    deltas = []
    for block in np.array_split(np.arange(k), N_BLOCKS):
        keep = np.setdiff1d(np.arange(k), block)
        rows = (3 * keep[:, None] + np.arange(3)).ravel()
        deltas.append(np.linalg.lstsq(af[rows], -r[rows], rcond=None)[0])
    deltas = np.array(deltas) - np.mean(deltas, axis=0)
    np.testing.assert_allclose(jack, (N_BLOCKS - 1) / N_BLOCKS * deltas.T @ deltas, rtol=1e-8)


def test_magnetometer_alignment_covariance_carries_the_frame_through_alpha():
    """``T_R``'s covariance: the jackknife of a small rotation of B plus the frame's own, both
    carried to the rotation vector alpha by ``J C J^T``; with a frame covariance only in one
    axis and alpha 0.5 rad from zero (J not the identity, not symmetric) the added part is exactly
    ``J C_frame J^T``."""
    from imucal.fits.reference import fit_mag_to_reference

    rng = np.random.default_rng(48)
    n = 600
    to_world = Rotation.from_rotvec(rng.normal(0, 1.2, (n, 3)))
    t_r = Rotation.from_rotvec([0.3, -0.2, 0.4])
    world = np.array([0.4, 0.0, -0.9])
    field = t_r.inv().apply(to_world.apply(world, inverse=True)) + 0.01 * rng.standard_normal(
        (n, 3)
    )
    frame = np.diag([4e-4, 0.0, 0.0])
    plain = fit_mag_to_reference(field, to_world)
    framed = fit_mag_to_reference(field, to_world, frame)
    np.testing.assert_allclose(plain.alpha_rad, t_r.as_rotvec(), atol=5e-3)
    rotation = Rotation.from_rotvec(plain.alpha_rad)
    jac = np.column_stack(
        [((Rotation.from_rotvec(d) * rotation).as_rotvec()
          - (Rotation.from_rotvec(-d) * rotation).as_rotvec()) / 2e-7
         for d in 1e-7 * np.eye(3)]
    )  # fmt: skip
    np.testing.assert_allclose(
        framed.alpha_covariance - plain.alpha_covariance, jac @ frame @ jac.T, rtol=1e-5, atol=1e-12
    )


def test_constant_component_alignment_std_over_n_minus_3_minus_one_per_phase():
    """Eqs. 25-27 over all samples (``full``), white residuals: ``r.r / (N - 3 - n_phases)
    (J^T J)^-1``, each phase losing one dof to its constant; 8 samples a phase, where that
    is 15 % of the dof."""
    from imucal.fits.alignment import align_constant_component

    rng = np.random.default_rng(49)
    alpha = np.array([0.02, -0.015, 0.03])
    t_r = errormodel.rotation_matrix(alpha)
    phases = {}
    for a, label in enumerate("xyz"):
        angle = np.linspace(0, 2 * np.pi, 8, endpoint=False) + rng.uniform(0, 1)
        u = np.zeros((8, 3))
        j, k = (b for b in range(3) if b != a)
        u[:, a], u[:, j], u[:, k] = 0.4, 0.9 * np.cos(angle), 0.9 * np.sin(angle)
        phases[label] = u @ t_r + 0.01 * rng.standard_normal((8, 3))  # T_R v = u
    fit = align_constant_component(phases, correlated=False)

    def residuals(p):
        t = errormodel.rotation_matrix(p)
        return np.concatenate(
            [(v - v.mean(axis=0)) @ t["xyz".index(lb)] for lb, v in phases.items()]
        )

    r = residuals(fit.alpha_rad)
    jac = np.column_stack(
        [
            (residuals(fit.alpha_rad + d) - residuals(fit.alpha_rad - d)) / 2e-7
            for d in 1e-7 * np.eye(3)
        ]
    )
    want = r @ r / (r.size - 3 - 3) * np.linalg.inv(jac.T @ jac)
    np.testing.assert_allclose(fit.covariance, want, rtol=1e-4)
    np.testing.assert_allclose(fit.std_alpha_rad, np.sqrt(np.diag(want)), rtol=1e-4)
