"""Gyroscope with a rate table (eq. 33): constant-rate runs about x, y and z of frame B.

Every run's true rate vector is known, so :func:`fit_rate_table` solves a *linear* least-squares
problem for the full matrix and the bias (closed-form covariance, equal to the Cramer-Rao bound,
:func:`rate_table_crlb`). Its upper-triangular factor is ``S'_gyr``; the rotation ``T_R,gyr``
comes from the platform phases. :func:`fit_rate_table_magnitude` is the magnitude-only
alternative; with runs about three axes it cannot observe the cross terms of ``S'`` (see its
Notes).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from imucal.errormodel import upper_triangular_factor
from imucal.fits.accelerometer import MagnitudeModelFit, fit_magnitude_model


@dataclass(frozen=True)
class RateTableFit:
    """Vector fit of the rate table runs (eq. 33): ``w_true = K (w_raw - b)``.

    Attributes
    ----------
    matrix : ndarray, shape (3, 3)
        ``K`` (maps bias-free readings to frame B).
    bias : ndarray, shape (3,)
        ``b``, rad/s.
    upper : ndarray, shape (3, 3)
        ``S'_gyr``: upper-triangular factor of ``K`` (``K = rotation @ upper``).
    rotation : ndarray, shape (3, 3)
        The rotation factor of ``K`` (the table's view of ``T_R,gyr``).
    covariance : ndarray, shape (12, 12)
        Covariance of ``(K row-major, b)`` (delta method from the exact covariance of
        ``(K^-1, b)``).
    std_matrix, std_upper : ndarray, shape (3, 3)
    std_bias : ndarray, shape (3,)
    noise_std_rad_s : ndarray, shape (3,)
        Noise of one sample per axis behind the covariance (given or from the residuals).
    residual_rad_s : ndarray, shape (n_runs, 3)
        ``w_raw - (K^-1 w_true + b)`` per run, rad/s.
    magnitude_error_before_rad_s, magnitude_error_after_rad_s : ndarray, shape (n_runs,)
        ``|w_raw| - |w_true|`` and ``|K (w_raw - b)| - |w_true|`` (the paper's Fig. 15).
    dof : int
        ``n_runs - 4`` (each axis: 3 matrix entries and a bias).
    """

    matrix: np.ndarray
    bias: np.ndarray
    upper: np.ndarray
    rotation: np.ndarray
    covariance: np.ndarray
    std_matrix: np.ndarray
    std_upper: np.ndarray
    std_bias: np.ndarray
    noise_std_rad_s: np.ndarray
    residual_rad_s: np.ndarray
    magnitude_error_before_rad_s: np.ndarray
    magnitude_error_after_rad_s: np.ndarray
    dof: int


def _check_runs(
    run_means: np.ndarray, rates_rad_s: np.ndarray, n_samples: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    w = np.asarray(run_means, dtype=float)
    r = np.asarray(rates_rad_s, dtype=float)
    n = np.asarray(n_samples, dtype=float)
    if w.ndim != 2 or w.shape[1] != 3 or r.shape != w.shape or n.shape != (len(w),):
        raise ValueError(
            f"expected run_means (n, 3), rates_rad_s (n, 3), n_samples (n,); got {w.shape}, "
            f"{r.shape}, {n.shape}"
        )
    for name, a in (("run_means", w), ("rates_rad_s", r)):
        bad = np.flatnonzero(~np.isfinite(a).all(axis=1))
        if len(bad):
            raise ValueError(f"{name}: runs {bad.tolist()} are not finite; expected finite rad/s")
    if np.any(n < 1):
        raise ValueError(f"n_samples must be >= 1 per run, got {n.tolist()}")
    return w, r, n


def _design(rates: np.ndarray) -> np.ndarray:
    design = np.column_stack([rates, np.ones(len(rates))])
    rank = np.linalg.matrix_rank(design)
    if rank < 4:
        raise ValueError(
            f"the true rate vectors span {rank - 1} dimension(s) plus the bias; expected runs about "
            "three independent axes (and rates of both signs or a zero run)"
        )
    return design


def _upper_jacobian(matrix: np.ndarray) -> np.ndarray:
    """d vec(upper factor) / d vec(matrix), shape (9, 9), by central differences."""
    h = 1e-7
    jac = np.zeros((9, 9))
    for i in range(9):
        step = np.zeros(9)
        step[i] = h
        plus = upper_triangular_factor(matrix + step.reshape(3, 3))[1]
        minus = upper_triangular_factor(matrix - step.reshape(3, 3))[1]
        jac[:, i] = (plus - minus).ravel() / (2 * h)
    return jac


def fit_rate_table(
    run_means: np.ndarray,
    rates_rad_s: np.ndarray,
    n_samples: np.ndarray,
    *,
    noise_std_rad_s: np.ndarray | None = None,
) -> RateTableFit:
    """Full matrix and bias from rate-table runs by linear least squares (eq. 33, vector form).

    Parameters
    ----------
    run_means : ndarray, shape (n_runs, 3)
        Mean gyroscope reading of each steady run, rad/s (sensor frame).
    rates_rad_s : ndarray, shape (n_runs, 3)
        True rate vector of each run in frame B: nominal rate times the unit table axis, rad/s.
    n_samples : ndarray, shape (n_runs,)
        Samples behind each mean (weights).
    noise_std_rad_s : ndarray, shape (3,), optional
        White-noise std of one sample per axis. If given, the covariance is the Cramer-Rao bound
        for that noise; otherwise the noise is estimated from the weighted residuals
        (``dof = n_runs - 4``), which also absorbs run-to-run errors of the table.

    Returns
    -------
    RateTableFit

    Raises
    ------
    ValueError
        On shape mismatches, non-finite values, or rates that do not span three axes.

    Notes
    -----
    ``w_true = K (w_raw - b)`` is ``w_raw = A w_true + b`` with ``A = K^-1``: for each sensor axis
    ``k`` a linear regression of ``w_raw[:, k]`` on ``(w_true, 1)`` with weights ``n_j``. The
    estimate of ``(A, b)`` is exact least squares with covariance ``sigma_k^2 (X^T N X)^-1`` per
    row, which is the Cramer-Rao bound for Gaussian noise (the problem is linear-Gaussian).
    ``K = A^-1`` and its QR factor follow by the delta method (first order).
    """
    w, r, n = _check_runs(run_means, rates_rad_s, n_samples)
    design = _design(r)
    gram_inv = np.linalg.inv(design.T @ (n[:, None] * design))
    coef = gram_inv @ design.T @ (n[:, None] * w)  # (4, 3): rows A^T then b
    a = coef[:3].T
    bias = coef[3]
    residual = w - design @ coef
    dof = len(w) - 4
    if noise_std_rad_s is None:
        if dof < 1:
            raise ValueError(
                f"{len(w)} runs leave no residual degrees of freedom to estimate the noise; "
                "pass noise_std_rad_s or use at least 5 runs"
            )
        noise = np.sqrt(np.sum(n[:, None] * residual**2, axis=0) / dof)
    else:
        noise = np.asarray(noise_std_rad_s, dtype=float).reshape(3)
    matrix = np.linalg.inv(a)
    covariance = _matrix_bias_covariance(matrix, gram_inv, noise)
    rotation, upper = upper_triangular_factor(matrix)
    j_upper = _upper_jacobian(matrix)
    cov_upper = j_upper @ covariance[:9, :9] @ j_upper.T
    calibrated = (w - bias) @ matrix.T
    return RateTableFit(
        matrix=matrix,
        bias=bias,
        upper=upper,
        rotation=rotation,
        covariance=covariance,
        std_matrix=np.sqrt(np.diag(covariance)[:9]).reshape(3, 3),
        std_upper=np.sqrt(np.clip(np.diag(cov_upper), 0, None)).reshape(3, 3),
        std_bias=np.sqrt(np.diag(covariance)[9:]),
        noise_std_rad_s=noise,
        residual_rad_s=residual,
        magnitude_error_before_rad_s=np.linalg.norm(w, axis=1) - np.linalg.norm(r, axis=1),
        magnitude_error_after_rad_s=np.linalg.norm(calibrated, axis=1) - np.linalg.norm(r, axis=1),
        dof=dof,
    )


def _matrix_bias_covariance(
    matrix: np.ndarray, gram_inv: np.ndarray, noise: np.ndarray
) -> np.ndarray:
    """Covariance of ``(K row-major, b)`` from that of ``(A = K^-1, b)``, shape (12, 12)."""
    # parameters of sensor row k: (A[k, :], b[k]) with covariance noise_k^2 * gram_inv;
    # rows are independent (each axis has its own noise)
    cov_ab = np.zeros((12, 12))  # order: A row-major (9), b (3)
    for k in range(3):
        idx = [3 * k, 3 * k + 1, 3 * k + 2, 9 + k]
        cov_ab[np.ix_(idx, idx)] = noise[k] ** 2 * gram_inv
    # dK = -K dA K  ->  dK_ij / dA_ab = -K_ia K_bj
    jac = np.zeros((12, 12))
    jac[:9, :9] = -np.einsum("ia,bj->ijab", matrix, matrix).reshape(9, 9)
    jac[9:, 9:] = np.eye(3)
    return jac @ cov_ab @ jac.T


def rate_table_crlb(
    matrix: np.ndarray,
    rates_rad_s: np.ndarray,
    n_samples: np.ndarray,
    noise_std_rad_s: np.ndarray,
) -> np.ndarray:
    """Cramer-Rao bound of ``(K row-major, b)`` for the rate table at a known truth.

    Parameters
    ----------
    matrix : ndarray, shape (3, 3)
        True ``K``.
    rates_rad_s : ndarray, shape (n_runs, 3)
        True rate vectors, rad/s.
    n_samples : ndarray, shape (n_runs,)
    noise_std_rad_s : ndarray, shape (3,)
        Sample white noise per axis, rad/s.

    Returns
    -------
    ndarray, shape (12, 12)
        Exact for ``(K^-1, b)`` (linear-Gaussian), mapped to ``K`` to first order.
    """
    r = np.asarray(rates_rad_s, dtype=float)
    n = np.asarray(n_samples, dtype=float)
    design = _design(r)
    gram_inv = np.linalg.inv(design.T @ (n[:, None] * design))
    return _matrix_bias_covariance(
        np.asarray(matrix, dtype=float), gram_inv, np.asarray(noise_std_rad_s, dtype=float)
    )


def fit_rate_table_magnitude(
    run_means: np.ndarray,
    rates_rad_s: np.ndarray,
    n_samples: np.ndarray,
    noise_std_rad_s: np.ndarray,
) -> MagnitudeModelFit:
    """Magnitude-only rate-table fit: ``|S'(w_raw - o)| = |rate|`` (LM, as eq. 32 for the cube).

    Parameters
    ----------
    run_means : ndarray, shape (n_runs, 3)
        Mean reading of each run, rad/s.
    rates_rad_s : ndarray, shape (n_runs, 3)
        True rate vectors, rad/s; only their norms are used. Zero-rate runs are left out (the
        norm is not differentiable at zero).
    n_samples : ndarray, shape (n_runs,)
    noise_std_rad_s : ndarray, shape (3,)
        Sample white noise per axis, rad/s (the residual weights).

    Returns
    -------
    MagnitudeModelFit
        Check ``singular_values``: a smallest-to-largest ratio near zero means some parameters
        are not determined by the data and their values are those of the starting point.

    Notes
    -----
    With runs about the three axes of B only, the readings lie on three lines through the
    bias, ``w = A r e_k + b``, and ``|S' A r e_k| = |r|`` for all rates ``r`` only constrains the
    three column norms of ``S' A``. Of the 6 entries of ``S'`` just 3 combinations are
    observable (with the 3 bias components): the cross terms are not, unlike the cube, whose
    45-degree positions add directions. Use :func:`fit_rate_table` (vector form) instead.
    """
    w, r, n = _check_runs(run_means, rates_rad_s, n_samples)
    norms = np.linalg.norm(r, axis=1)
    moving = norms > 0
    w, norms, n = w[moving], norms[moving], n[moving]
    # start: bias from the mean of the runs (rates of both signs cancel), isotropic scale
    bias0 = w.mean(axis=0)
    scale0 = np.sum(norms) / np.sum(np.linalg.norm(w - bias0, axis=1))
    return fit_magnitude_model(w, norms, n, noise_std_rad_s, scale0 * np.eye(3), bias0)
