"""Covariance of calibration parameters: delta method, goodness of fit, the file form."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from imucal import errormodel, uncertainty
from imucal.calibration import ImuCalibration, SensorCalibration

MATRIX = errormodel.compose([1.05, 0.97, 1.01], [0.01, -0.02, 0.015], [0.02, -0.01, 0.03])
BIAS = np.array([0.1, -0.2, 0.05])


def test_calibration_covariance_matches_sampling():
    """The delta method's std of scale, xi, alpha equals the scatter of decompose() over draws."""
    rng = np.random.default_rng(1)
    cov12 = np.diag(np.r_[np.full(3, 1e-6), np.full(9, 1e-8)])
    cov21 = uncertainty.calibration_covariance(BIAS, MATRIX, cov12)
    draws = rng.multivariate_normal(np.r_[BIAS, MATRIX.ravel()], cov12, size=4000)
    derived = []
    for d in draws:
        dec = errormodel.decompose(d[3:].reshape(3, 3))
        derived.append(np.concatenate([d, dec.scale, dec.xi_rad, dec.alpha_rad]))
    derived = np.array(derived)
    # the sample std of 4000 draws is within 5 % of the truth (its own relative std is 1.1 %)
    np.testing.assert_allclose(derived.std(axis=0), np.sqrt(np.diag(cov21)), rtol=0.05)


def test_two_step_covariance_without_alignment_error_is_step_one():
    _, upper = errormodel.upper_triangular_factor(MATRIX)
    c1 = np.diag(np.r_[np.full(6, 1e-8), np.full(3, 1e-6)])
    cov = uncertainty.two_step_covariance(
        upper, BIAS, c1, np.zeros(3), np.zeros((3, 3)), np.zeros((3, 9))
    )
    np.testing.assert_allclose(np.diag(cov)[:3], 1e-6, rtol=1e-6)
    # T_R = I: the matrix is S' itself, entries below the diagonal have no variance
    matrix_var = np.diag(cov)[3:12].reshape(3, 3)
    np.testing.assert_allclose(matrix_var[np.triu_indices(3)], 1e-8, rtol=1e-5)
    np.testing.assert_allclose(matrix_var[np.tril_indices(3, -1)], 0.0, atol=1e-16)


def test_sensitivity_carries_step_one_into_alpha():
    _, upper = errormodel.upper_triangular_factor(MATRIX)
    c1 = np.diag(np.r_[np.full(6, 1e-8), np.full(3, 1e-6)])
    g = np.zeros((3, 9))
    g[0, 6] = 0.5  # alpha_x moves by half of o_x
    cov = uncertainty.two_step_covariance(upper, BIAS, c1, np.zeros(3), np.eye(3) * 1e-10, g)
    alpha = uncertainty.GROUPS["alpha_rad"]
    assert np.diag(cov)[alpha][0] == pytest.approx(0.25e-6 + 1e-10, rel=1e-4)
    # and alpha_x is correlated with o_x (correlation 1 up to the alignment's own 1e-10)
    corr = cov[alpha.start, 0] / np.sqrt(cov[alpha.start, alpha.start] * cov[0, 0])
    assert corr == pytest.approx(1.0, abs=1e-3)


def test_goodness_of_fit_inflates_only_beyond_the_quantile():
    dof = 29
    limit = stats.chi2.ppf(uncertainty.INFLATION_QUANTILE, dof)
    assert uncertainty.goodness_of_fit(limit * 0.99, dof).inflation == 1.0
    fit = uncertainty.goodness_of_fit(442.0, dof)  # the imu_tk cube fit
    assert fit.inflation == pytest.approx(442.0 / 29)
    assert fit.p_value < 1e-10
    with pytest.raises(ValueError, match="dof >= 1"):
        uncertainty.goodness_of_fit(3.0, 0)


def test_covariance_round_trips_and_old_files_load():
    cov = uncertainty.calibration_covariance(BIAS, MATRIX, np.eye(12) * 1e-8)
    cal = SensorCalibration(
        "acc", BIAS, MATRIX, "m/s^2", uncertainty.std_of(cov), "x", cov, {"cube": {"rule": "r"}}
    )
    d = cal.to_dict()
    assert d["covariance"]["parameters"] == list(uncertainty.PARAMETERS)
    back = SensorCalibration.from_dict("acc", d)
    np.testing.assert_array_equal(back.covariance, cov)
    assert back.quality == {"cube": {"rule": "r"}}
    old = {k: v for k, v in d.items() if k not in ("covariance", "quality")}
    assert SensorCalibration.from_dict("acc", old).covariance is None
    d["covariance"]["parameters"] = d["covariance"]["parameters"][::-1]
    with pytest.raises(ValueError, match="covariance of 'acc' is over the parameters"):
        SensorCalibration.from_dict("acc", d)
    with pytest.raises(ValueError, match=r"must be a finite \(21, 21\)"):
        SensorCalibration("acc", BIAS, MATRIX, "m/s^2", covariance=np.eye(12))
    full = ImuCalibration(
        cal,
        cal.__class__("gyr", BIAS, MATRIX, "rad/s"),
        back.__class__("mag", BIAS, MATRIX, "normalised"),
    )
    assert "covariance" not in full.to_dict()["gyr"]


def test_calibrated_covariance_matches_sampling():
    """Cov of matrix (r - bias) over draws of (bias, matrix) equals the analytic J C J^T."""
    rng = np.random.default_rng(3)
    a = rng.normal(size=(12, 12)) * 1e-3
    cov12 = a @ a.T
    readings = np.array([[9.8, 0.1, -0.3], [0.0, 0.0, 0.0], [-3.0, 5.0, 7.0]])
    analytic = uncertainty.calibrated_covariance(MATRIX, BIAS, cov12, readings)
    draws = rng.multivariate_normal(np.r_[BIAS, MATRIX.ravel()], cov12, size=20000)
    for i, r in enumerate(readings):
        values = np.array([d[3:].reshape(3, 3) @ (r - d[:3]) for d in draws])
        # a sample covariance of 20000 draws: entries within 4 % of the largest variance
        scale = np.max(np.diag(analytic[i]))
        np.testing.assert_allclose(np.cov(values.T), analytic[i], atol=0.04 * scale)


def test_two_step_covariance_at_large_alpha_uses_the_exact_rotation():
    """At alpha of 0.3 rad the exact and the small-angle T_R differ at first order in the
    covariance of the matrix: the default (exact) must match a sampling of the exact model, and
    differ from exact=False."""
    rng = np.random.default_rng(2)
    _, upper = errormodel.upper_triangular_factor(MATRIX)
    alpha = np.array([0.3, -0.2, 0.25])
    c1 = np.diag(np.r_[np.full(6, 1e-8), np.full(3, 1e-6)])
    c_alpha = np.eye(3) * 1e-6
    g = np.zeros((3, 9))
    cov = uncertainty.two_step_covariance(upper, BIAS, c1, alpha, c_alpha, g)
    small = uncertainty.two_step_covariance(upper, BIAS, c1, alpha, c_alpha, g, exact=False)
    draws = []
    for _ in range(4000):
        u = upper + uncertainty.upper_matrix(1e-4 * rng.standard_normal(6))
        a = alpha + 1e-3 * rng.standard_normal(3)
        draws.append((errormodel.rotation_matrix(a, exact=True) @ u).ravel())
    sampled = np.std(draws, axis=0)
    np.testing.assert_allclose(np.sqrt(np.diag(cov)[3:12]), sampled, rtol=0.06)
    assert np.max(np.abs(np.sqrt(np.diag(small)[3:12]) / sampled - 1)) > 0.15


def test_numerical_jacobian_scales_its_step_with_the_value():
    """The step is rel_step * max(1, |x|): exact for a quadratic far from 1 and near 0."""
    jac = uncertainty.numerical_jacobian(lambda x: x**2, np.array([1e6, 3e-3]))
    np.testing.assert_allclose(np.diag(jac), [2e6, 6e-3], rtol=1e-9)
    # integers are differentiated as the floats they stand for
    jac = uncertainty.numerical_jacobian(lambda x: x**2, [3, 4])
    np.testing.assert_allclose(np.diag(jac), [6.0, 8.0], rtol=1e-9)


def test_covariance_checks_and_std_of_edge_cases():
    with pytest.raises(ValueError, match=r"expected a finite \(12, 12\) covariance, got shape"):
        uncertainty.calibration_covariance(BIAS, MATRIX, np.eye(9))
    assert uncertainty.std_of(None) == {}
    diag = np.full(21, 1e-6)
    diag[0] = -1e-20  # round-off below zero: std 0, not NaN
    std = uncertainty.std_of(np.diag(diag))
    assert std["bias"][0] == 0.0 and std["bias"][1] == pytest.approx(1e-3)
    assert std["matrix"].shape == (3, 3) and np.all(std["matrix"] == pytest.approx(1e-3))


def test_goodness_of_fit_bounds():
    fit = uncertainty.goodness_of_fit(0.0, 1)
    assert (fit.chi2, fit.dof, fit.p_value, fit.inflation) == (0.0, 1, 1.0, 1.0)
    for chi2 in (np.nan, np.inf, -1e-9):
        with pytest.raises(ValueError, match="chi2 must be finite and >= 0"):
            uncertainty.goodness_of_fit(chi2, 3)
    with pytest.raises(ValueError, match="dof >= 1, got 0"):
        uncertainty.goodness_of_fit(1.0, 0)


def test_calibrated_covariance_reads_the_first_12_of_a_21_covariance():
    rng = np.random.default_rng(3)
    a = rng.standard_normal((21, 21))
    cov21 = a @ a.T * 1e-6
    readings = rng.standard_normal((4, 3))
    got = uncertainty.calibrated_covariance(MATRIX, BIAS, cov21, readings)
    want = uncertainty.calibrated_covariance(MATRIX, BIAS, cov21[:12, :12], readings)
    np.testing.assert_allclose(got, want, rtol=1e-12)


def test_joint_covariance_from_blocks_and_step_one_alone():
    rng = np.random.default_rng(5)
    a = rng.standard_normal((12, 12))
    full = a @ a.T
    joint = uncertainty.bias_matrix_covariance(full[:3, :3], full[3:, 3:], full[3:, :3])
    np.testing.assert_array_equal(joint, full)
    apart = uncertainty.bias_matrix_covariance(full[:3, :3], full[3:, 3:])
    np.testing.assert_array_equal(apart[3:, :3], 0.0)
    np.testing.assert_array_equal(apart[:3, :3], full[:3, :3])
    # matrix = S': the covariance of its upper entries and of o is step 1's, below the
    # diagonal nothing
    _, upper = errormodel.upper_triangular_factor(MATRIX)
    b = rng.standard_normal((9, 9))
    c1 = b @ b.T * 1e-8
    cov = uncertainty.step1_only_covariance(upper, BIAS, c1)
    assert cov.shape == (21, 21)
    rows = 3 + np.flatnonzero(np.triu(np.ones((3, 3))).ravel())
    np.testing.assert_allclose(cov[np.ix_(rows, rows)], c1[:6, :6], rtol=1e-6, atol=1e-18)
    np.testing.assert_allclose(cov[:3, :3], c1[6:, 6:], rtol=1e-6, atol=1e-18)
    np.testing.assert_allclose(cov[:3][:, rows], c1[6:, :6], rtol=1e-6, atol=1e-18)
    lower = 3 + np.flatnonzero(np.tril(np.ones((3, 3)), -1).ravel())
    np.testing.assert_allclose(cov[lower, lower], 0.0, atol=1e-20)


def test_goodness_of_fit_record():
    fit = uncertainty.goodness_of_fit(87.0, 29)
    d = fit.to_dict()
    assert d["chi2"] == 87.0 and d["dof"] == 29 and d["chi2_per_dof"] == pytest.approx(3.0)
    assert d["p_value"] == pytest.approx(stats.chi2.sf(87.0, 29), rel=1e-9)
    assert d["inflation"] == pytest.approx(3.0)
    assert d["rule"] == (
        f"covariance x chi2/dof when chi2 > the {uncertainty.INFLATION_QUANTILE:g} quantile of "
        "chi-square(dof)"
    )


def test_propagate_is_j_c_j_transpose_for_a_linear_map():
    """A linear map ``A x`` with ``A`` neither symmetric nor square: ``A C A^T`` exactly (the
    transpose on the wrong side, or none, gives another matrix)."""
    rng = np.random.default_rng(3)
    a = rng.standard_normal((4, 6))
    root = rng.standard_normal((6, 6))
    cov = root @ root.T
    out = uncertainty.propagate(lambda x: a @ x, rng.standard_normal(6), cov)
    np.testing.assert_allclose(out, a @ cov @ a.T, rtol=1e-7, atol=1e-9)


def test_two_step_joint_covariance_carries_step_one_through_the_sensitivity():
    """``(theta, alpha)`` with ``alpha = G theta + a``: the joint covariance is
    ``L diag(C1, C_alpha) L^T`` with ``L = [[I, 0], [G, I]]``, carried here to the calibration
    by central differences; the function's 21 x 21 must agree."""
    from imucal import errormodel

    rng = np.random.default_rng(4)
    upper = np.array([[1.1, 0.02, -0.03], [0.0, 0.95, 0.01], [0.0, 0.0, 1.05]])
    bias = np.array([0.1, -0.2, 0.05])
    alpha = np.array([0.05, -0.02, 0.3])
    r1, r2 = rng.standard_normal((9, 9)), rng.standard_normal((3, 3))
    c1, ca = 1e-4 * r1 @ r1.T, 1e-5 * r2 @ r2.T
    g = rng.standard_normal((3, 9))
    lower = np.block([[np.eye(9), np.zeros((9, 3))], [g, np.eye(3)]])
    joint = lower @ np.block([[c1, np.zeros((9, 3))], [np.zeros((3, 9)), ca]]) @ lower.T
    theta = np.concatenate([upper[np.triu_indices(3)], bias, alpha])

    def calibration(p):
        u = np.zeros((3, 3))
        u[np.triu_indices(3)] = p[:6]
        return np.concatenate([p[6:9], (errormodel.rotation_matrix(p[9:]) @ u).ravel()])

    jac = np.column_stack(
        [(calibration(theta + d) - calibration(theta - d)) / 2e-7 for d in 1e-7 * np.eye(12)]
    )
    want = uncertainty.calibration_covariance(
        bias, errormodel.rotation_matrix(alpha) @ upper, jac @ joint @ jac.T
    )
    got = uncertainty.two_step_covariance(upper, bias, c1, alpha, ca, g)
    np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-12)
