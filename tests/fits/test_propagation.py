"""Step 1 -> step 2 propagation and the alignment's sandwich covariance, against simulation."""

from __future__ import annotations

import numpy as np
from scipy import signal, stats

from imucal import errormodel, uncertainty
from imucal.fits.alignment import align_constant_component, align_rotation_axis
from imucal.fits.propagation import alignment_sensitivity

ALPHA = np.array([0.02, -0.015, 0.03])
UPPER = np.array([[1.03, 0.012, -0.02], [0.0, 0.98, 0.015], [0.0, 0.0, 1.01]])
BIAS = np.array([0.05, -0.08, 0.1])
N = 600


def _circles() -> dict[str, np.ndarray]:
    """Unit vectors of frame B turning twice about each axis (step-2 truth: ``T_R v' = u``)."""
    out = {}
    for a, (label, c) in enumerate(zip("xyz", (0.3, -0.45, -0.85), strict=True)):
        phi = np.linspace(0, 4 * np.pi, N, endpoint=False) + a
        b, d = (k for k in range(3) if k != a)
        u = np.zeros((N, 3))
        u[:, a] = c
        u[:, b] = np.sqrt(1 - c * c) * np.cos(phi)
        u[:, d] = np.sqrt(1 - c * c) * np.sin(phi)
        out[label] = u
    return out


def _filtered_noise(rng, shape, std) -> np.ndarray:
    """White noise through a zero-phase 4th-order low-pass at a tenth of Nyquist: neighbours
    share noise, as in the low-pass filtered rotation3d phases."""
    b, a = signal.butter(4, 0.1)
    x = signal.filtfilt(b, a, rng.normal(size=shape), axis=0)
    return std * x / x.std()


def _chi2_bounds(dof: int) -> tuple[float, float]:
    return stats.chi2.ppf(0.0005, dof), stats.chi2.ppf(0.9995, dof)


def test_sandwich_covariance_is_honest_for_filtered_noise():
    """Sum of z^2 of alpha over 30 seeds within the 99.9 % chi-square(90) interval."""
    t_r = errormodel.rotation_matrix(ALPHA)
    truth = {k: u @ t_r for k, u in _circles().items()}  # v' = T_R^T u
    z2 = 0.0
    for seed in range(30):
        rng = np.random.default_rng(seed)
        phases = {k: v + _filtered_noise(rng, v.shape, 0.01) for k, v in truth.items()}
        fit = align_constant_component(phases)
        err = fit.alpha_rad - ALPHA
        z2 += float(err @ np.linalg.solve(fit.covariance, err))
    low, high = _chi2_bounds(90)
    assert low < z2 < high, (z2, low, high)


def test_two_step_covariance_is_honest():
    """Step 1 known up to a drawn error with covariance C1, step 2 fitted through it: the
    Mahalanobis distance of (bias, matrix) with the propagated covariance is chi-square(12)."""
    t_r = errormodel.rotation_matrix(ALPHA)
    raw = {k: errormodel.invert(t_r @ UPPER, BIAS, u) for k, u in _circles().items()}
    c1 = np.diag(np.r_[np.full(6, 4e-6), np.full(3, 1e-4)])
    theta = np.r_[uncertainty.upper_entries(UPPER), BIAS]
    z2, dof = 0.0, 0
    for seed in range(12):
        rng = np.random.default_rng(100 + seed)
        est = rng.multivariate_normal(theta, c1)
        upper, bias = uncertainty.upper_matrix(est[:6]), est[6:]
        phases = {k: r + _filtered_noise(rng, r.shape, 0.005) for k, r in raw.items()}

        def align(ph):
            return align_constant_component(ph)

        fit = align({k: errormodel.apply(upper, bias, v) for k, v in phases.items()})
        g = alignment_sensitivity(align, phases, upper, bias)
        cov = uncertainty.two_step_covariance(upper, bias, c1, fit.alpha_rad, fit.covariance, g)
        err = np.r_[bias - BIAS, (fit.matrix @ upper - t_r @ UPPER).ravel()]
        z2 += float(err @ np.linalg.solve(cov[:12, :12], err))
        dof += 12
    low, high = _chi2_bounds(dof)
    assert low < z2 < high, (z2, low, high)


def test_sensitivity_of_the_rotation_axis_to_the_bias():
    """Analytic case: constant rate r about each axis, T_R = I, S' = I. A bias error d moves the
    rates by -d; alpha_z enters the y row of phase x (alpha_z r - d_y) and the x row of phase y
    (-alpha_z r - d_x), so least squares gives alpha_z = (d_y - d_x) / (2 r)."""
    rate = 2.0
    phases = {}
    for a, label in enumerate("xyz"):
        w = np.zeros((N, 3))
        w[:, a] = rate
        phases[label] = w
    g = alignment_sensitivity(align_rotation_axis, phases, np.eye(3), np.zeros(3))
    # forward differences with a relative step of 1e-5: second-order error ~ 1e-5 relative
    np.testing.assert_allclose(g[2, 6:], [-1 / (2 * rate), 1 / (2 * rate), 0.0], atol=1e-5)
    np.testing.assert_allclose(g[0, 6:], [0.0, -1 / (2 * rate), 1 / (2 * rate)], atol=1e-5)


def test_upper_bias_covariance_matches_sampling():
    """The delta method's covariance of (S' upper entries, o) from that of (K, o), against the
    scatter of the QR factor of 4000 draws of K (rtol 6 %: the sample std's own 1.1 %)."""
    from imucal import errormodel
    from imucal.fits.propagation import upper_bias_covariance

    rng = np.random.default_rng(6)
    k = errormodel.compose([1.1, 0.9, 1.05], [0.01, -0.02, 0.015], [0.1, -0.05, 0.2])
    a = rng.standard_normal((12, 12))
    cov = a @ a.T * 1e-8
    got = upper_bias_covariance(k, cov)
    draws = rng.multivariate_normal(np.r_[k.ravel(), np.zeros(3)], cov, size=4000)
    sampled = [
        np.r_[errormodel.upper_triangular_factor(d[:9].reshape(3, 3))[1][np.triu_indices(3)], d[9:]]
        for d in draws
    ]
    np.testing.assert_allclose(np.sqrt(np.diag(got)), np.std(sampled, axis=0), rtol=0.06)
