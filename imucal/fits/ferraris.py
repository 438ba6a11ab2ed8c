"""Known-orientation calibration (Ferraris protocol): six faces and known-angle rotations.

A partial protocol without the paper's platform: the module is placed on each of its six faces
(each axis of frame B pointing up, then down), then turned by hand through a known angle
(usually 360 degrees) about each axis of B. Frame B is *defined by the positions*: the face on
which axis ``x`` of B points up is the face whose label is ``x_p``.

* Accelerometer (:func:`fit_known_orientations`): the specific force at rest is ``g d_k`` with
  ``d_k`` the known up direction of position ``k`` in B. The model ``reading = A g d_k + o``
  (``A = matrix^-1``) is linear in ``(A, o)``: 12 unknowns, 3 equations per position, so four
  positions spanning 3-D suffice and the six faces leave 6 residual degrees of freedom. Unlike
  the magnitude fit of eq. 32 (:func:`imucal.fits.accelerometer.fit_cube`) the result includes the
  rotation into B (full matrix = ``T_R T_N S``), because the directions are known.
* Gyroscope (:func:`fit_known_rotations`): the bias-corrected raw rate integrated over a
  rotation section is the raw angle vector; the matrix maps it to the known angle vector
  (eq. 36 of the paper generalised from one scale per phase to the full matrix, the approach of
  Ferraris et al. 1995). The integral of the body rate equals the rotation vector only for a
  rotation about a fixed body axis; hand wobble that returns to the start cancels to first order.

References
----------
Ferraris, Grimaldi, Parvis, "Procedure for effortless in-field calibration of three-axial rate
gyro and accelerometers", Sensors and Materials 7(5), 1995.
Zhang, Hoeflinger, Reindl, IEEE Sensors J. 14(6), 2014, eqs. 11 and 36.

The two fits of the Ferraris protocol share its sections and their checks, and each carries
its covariance beside its estimator.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from imucal import errormodel, uncertainty
from imucal.calibration import SensorCalibration

#: Up direction in frame B of the six Ferraris faces (``p``: axis up, ``a``: axis down).
FACE_DIRECTIONS: dict[str, np.ndarray] = {
    "x_p": np.array([1.0, 0.0, 0.0]),
    "x_a": np.array([-1.0, 0.0, 0.0]),
    "y_p": np.array([0.0, 1.0, 0.0]),
    "y_a": np.array([0.0, -1.0, 0.0]),
    "z_p": np.array([0.0, 0.0, 1.0]),
    "z_a": np.array([0.0, 0.0, -1.0]),
}
#: The affine model ``A g d + o`` has 4 unknowns per axis.
MIN_POSITIONS = 4
#: Fewest samples in a position or rotation section.
MIN_SAMPLES = 2
#: Smallest accepted ratio of the smallest to the largest singular value of a design.
MIN_CONDITION = 1e-3


def _propagate(
    func: Callable[[np.ndarray], np.ndarray], x: np.ndarray, cov: np.ndarray
) -> np.ndarray:
    """Covariance of ``func(x)`` by first-order propagation (central differences), shape (m, m)."""
    x = np.asarray(x, dtype=float)
    f0 = np.asarray(func(x), dtype=float).ravel()
    jac = np.zeros((f0.size, x.size))
    for i in range(x.size):
        step = 1e-6 * max(1.0, abs(x[i]))
        dx = np.zeros_like(x)
        dx[i] = step
        jac[:, i] = (np.ravel(func(x + dx)) - np.ravel(func(x - dx))) / (2 * step)
    return jac @ cov @ jac.T


def _decomposition_std(matrix: np.ndarray, cov_matrix: np.ndarray) -> dict[str, np.ndarray]:
    """Std of scale, xi and alpha from the covariance (9, 9) of the row-major matrix entries."""

    def parts(m: np.ndarray) -> np.ndarray:
        d = errormodel.decompose(m.reshape(3, 3))
        return np.concatenate([d.scale, d.xi_rad, d.alpha_rad])

    std = np.sqrt(np.clip(np.diag(_propagate(parts, matrix.ravel(), cov_matrix)), 0, None))
    return {"scale": std[:3], "xi_rad": std[3:6], "alpha_rad": std[6:]}


def _check_samples(values: np.ndarray, name: str) -> np.ndarray:
    v = np.asarray(values, dtype=float)
    if v.ndim != 2 or v.shape[1] != 3 or len(v) < MIN_SAMPLES:
        raise ValueError(f"{name}: expected shape (n, 3) with n >= {MIN_SAMPLES}, got {v.shape}")
    if not np.all(np.isfinite(v)):
        raise ValueError(f"{name}: {int(np.sum(~np.isfinite(v).all(axis=1)))} rows not finite")
    return v


def _check_proper(matrix: np.ndarray, sensor: str, hint: str) -> None:
    det = float(np.linalg.det(matrix))
    if not det > 0:
        raise ValueError(
            f"the fitted {sensor} matrix mirrors the axes (determinant {det:.3g}, expected > 0); "
            f"check {hint}"
        )


# --------------------------------------------------------------------------------------------
# Accelerometer: positions with known up direction
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class KnownOrientationFit:
    """Accelerometer calibration from static positions of known orientation.

    Attributes
    ----------
    calibration : SensorCalibration
        ``matrix`` (3, 3) maps a bias-free reading to frame B of the positions; ``bias`` (3,)
        m/s^2; ``std`` holds 'bias', 'matrix', 'scale', 'xi_rad', 'alpha_rad'.
    labels : tuple of str
        Label of each position.
    position_means : ndarray, shape (n_pos, 3)
        Mean reading of each position, m/s^2.
    directions : ndarray, shape (n_pos, 3)
        Unit up direction of each position in B.
    residuals_m_s2 : ndarray, shape (n_pos, 3)
        ``matrix (mean - bias) - g d`` per position, m/s^2 (in-sample).
    magnitude_error_m_s2 : ndarray, shape (n_pos,)
        ``|matrix (mean - bias)| - g`` per position, m/s^2 (in-sample).
    residual_std_m_s2 : float
        Pooled std of the equal-weight reading residuals ``mean - (A g d + o)`` (sensor frame,
        m/s^2) with ``dof`` degrees of freedom.
    placement_std_rad : float
        Estimated tilt of a position from its nominal direction (std per axis, rad) used by the
        'tilt' weighting; 0 for 'equal'.
    dof : int
        ``3 (n_pos - 4)``.
    """

    calibration: SensorCalibration
    labels: tuple[str, ...]
    position_means: np.ndarray
    directions: np.ndarray
    residuals_m_s2: np.ndarray
    magnitude_error_m_s2: np.ndarray
    residual_std_m_s2: float
    placement_std_rad: float
    dof: int


_WEIGHTINGS = ("tilt", "equal")


def _tilt_weighted(
    positions: Sequence[np.ndarray],
    means: np.ndarray,
    d: np.ndarray,
    g: float,
    theta: np.ndarray,
    dof: int,
) -> tuple[np.ndarray, np.ndarray, float]:
    """Generalised least squares with a placement-tilt error model; returns theta, cov, tilt.

    A position tilted by a small angle (std ``tau`` per axis) moves the specific force by
    ``g tau`` across its direction and only by ``g tau^2 / 2`` along it, so in the reading
    frame the mean of position k has the covariance
    ``diag(var_k) / n_k + tau^2 g^2 A (I - d_k d_k^T) A^T``. ``tau`` is set so that the
    weighted chi-square equals the degrees of freedom (0 if the sample noise alone explains
    the residuals).
    """
    # floor: a constant (noise-free) reading still has its rounding; keeps the weights finite
    floor = (1e-9 * g) ** 2
    noise = [
        np.maximum(np.var(np.asarray(p, dtype=float), axis=0, ddof=1) / len(p), floor)
        for p in positions
    ]
    rows = [np.hstack([np.kron(np.eye(3), g * dk[None, :]), np.eye(3)]) for dk in d]

    def solve(theta0: np.ndarray, tau: float) -> tuple[np.ndarray, np.ndarray, float]:
        a = theta0[:9].reshape(3, 3)
        info = np.zeros((12, 12))
        rhs = np.zeros(12)
        weights = []
        for x, m, dk, nv in zip(rows, means, d, noise):
            cov = np.diag(nv) + tau**2 * g**2 * a @ (np.eye(3) - np.outer(dk, dk)) @ a.T
            w = np.linalg.inv(cov)
            weights.append(w)
            info += x.T @ w @ x
            rhs += x.T @ w @ m
        new = np.linalg.solve(info, rhs)
        chi2 = sum(
            float((m - x @ new) @ w @ (m - x @ new)) for x, m, w in zip(rows, means, weights)
        )
        return new, np.linalg.inv(info), chi2

    tau = 0.0
    for _ in range(3):
        if solve(theta, 0.0)[2] <= dof:
            tau = 0.0
        else:
            lo, hi = 0.0, 0.5  # rad; the chi-square falls monotonically with tau
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                lo, hi = (mid, hi) if solve(theta, mid)[2] > dof else (lo, mid)
            tau = hi
        theta, cov, _ = solve(theta, tau)
    return theta, cov, tau


def fit_known_orientations(
    positions: Sequence[np.ndarray],
    directions: np.ndarray,
    gravity_m_s2: float,
    *,
    labels: Sequence[str] | None = None,
    weighting: str = "tilt",
) -> KnownOrientationFit:
    """Fit the accelerometer matrix and bias to static positions of known orientation.

    Parameters
    ----------
    positions : sequence of ndarray, each shape (n_i, 3)
        Accelerometer readings of each static position, m/s^2 (sensor frame; a nominal
        sensitivity is enough, the matrix absorbs the scale).
    directions : ndarray, shape (n_pos, 3)
        Up direction of each position in frame B (the specific force at rest is
        ``gravity_m_s2 * direction``); normalised here. For the six faces use
        :data:`FACE_DIRECTIONS`.
    gravity_m_s2 : float
        Local gravity, m/s^2.
    labels : sequence of str, optional
        Position names for messages (default ``p01``...).
    weighting : {'tilt', 'equal'}
        'tilt' (default): generalised least squares with the placement-tilt error model (see
        Notes); 'equal': ordinary least squares on the position means.

    Returns
    -------
    KnownOrientationFit

    Raises
    ------
    ValueError
        Fewer than 4 positions, a position with fewer than 2 samples or non-finite values, or
        directions that do not span 3-D affinely (e.g. all faces of one axis).

    Notes
    -----
    Each position mean obeys ``mean_k = A g d_k + o + e_k`` (``A = matrix^-1``), linear in
    ``(A, o)``. The error ``e_k`` is dominated by how well the module sits on its face, not by
    the sensor noise averaged over the samples. A tilt moves the specific force across its
    direction to first order and along it only to second order, so the reading of an axis that
    points up or down is nearly tilt-free while the horizontal axes pick up ``g`` times the
    tilt. With equal weights (ordinary least squares; for the six faces the matrix columns are
    the half-differences of opposite faces, as in Ferraris's closed form, and the bias is the
    mean of all six faces) the tilt of the four faces on which an axis is horizontal enters
    that axis's bias to first order. The 'tilt' weighting models it: generalised least squares
    with the covariance ``diag(var_k) / n_k + tau^2 g^2 A (I - d_k d_k^T) A^T`` per position,
    ``tau`` estimated so that the chi-square equals the ``3 (n_pos - 4)`` dof. Its bias then
    comes mainly from the faces on which the axis is vertical (Ferraris's bias), and the
    covariance of the estimate is the inverse of the weighted information. The standard
    deviations therefore come from the residuals, not from the sample scatter; they propagate
    to ``matrix = A^-1`` and to its decomposition to first order. With exactly 4 positions
    there are no residual dof and no standard deviations.
    """
    if not np.isfinite(gravity_m_s2) or gravity_m_s2 <= 0:
        raise ValueError(f"gravity_m_s2 must be positive, got {gravity_m_s2!r}")
    if weighting not in _WEIGHTINGS:
        raise ValueError(f"weighting must be one of {_WEIGHTINGS}, got {weighting!r}")
    n_pos = len(positions)
    labels = tuple(labels) if labels is not None else tuple(f"p{i + 1:02d}" for i in range(n_pos))
    d = np.asarray(directions, dtype=float)
    if d.shape != (n_pos, 3) or len(labels) != n_pos:
        raise ValueError(
            f"{n_pos} positions need directions of shape ({n_pos}, 3) and {n_pos} labels, "
            f"got directions {d.shape} and {len(labels)} labels"
        )
    if n_pos < MIN_POSITIONS:
        raise ValueError(
            f"known-orientation fit needs at least {MIN_POSITIONS} positions (12 unknowns, "
            f"3 equations each; the Ferraris protocol uses 6 faces), got {n_pos}"
        )
    norms = np.linalg.norm(d, axis=1)
    if np.any(norms < 1e-9):
        raise ValueError(f"direction of position {labels[int(np.argmin(norms))]!r} is zero")
    d = d / norms[:, None]
    means = np.array(
        [_check_samples(p, f"position {lab!r}").mean(axis=0) for p, lab in zip(positions, labels)]
    )
    design = np.column_stack([gravity_m_s2 * d, np.ones(n_pos)])
    sv = np.linalg.svd(design, compute_uv=False)
    if sv[-1] < MIN_CONDITION * sv[0]:
        raise ValueError(
            f"the up directions of positions {list(labels)} do not span 3-D (design singular "
            f"values {sv.round(4).tolist()}); expected each axis of B both up and down"
        )
    coef, *_ = np.linalg.lstsq(design, means, rcond=None)  # shape (4, 3): column i = axis i
    resid_readings = means - design @ coef
    dof = 3 * (n_pos - MIN_POSITIONS)
    s2 = float(np.sum(resid_readings**2) / dof) if dof > 0 else np.nan
    theta = np.concatenate([coef[:3].T.ravel(), coef[3]])  # (A row-major, o)
    placement = 0.0
    if weighting == "tilt" and dof > 0:
        theta, cov, placement = _tilt_weighted(positions, means, d, gravity_m_s2, theta, dof)
    else:
        # equal weights: rows independent, each s2 (X^T X)^-1 over (A[i,:], o[i])
        xtx_inv = np.linalg.inv(design.T @ design)
        cov = np.zeros((12, 12))
        for i in range(3):
            idx = [3 * i, 3 * i + 1, 3 * i + 2, 9 + i]
            cov[np.ix_(idx, idx)] = s2 * xtx_inv
    a_inv = theta[:9].reshape(3, 3)  # reading = a_inv @ (g d) + o
    bias = theta[9:]
    matrix = np.linalg.inv(a_inv)
    _check_proper(matrix, "accelerometer", "the up directions (labels p/a swapped?)")
    covariance = None
    if dof > 0:
        # (o, K = A^-1) from (A row-major, o), then scale, xi, alpha (delta method)
        cov_bias_matrix = uncertainty.propagate(
            lambda t: np.concatenate([t[9:], np.linalg.inv(t[:9].reshape(3, 3)).ravel()]),
            theta,
            cov,
        )
        covariance = uncertainty.calibration_covariance(bias, matrix, cov_bias_matrix)
        std = uncertainty.std_of(covariance)
    else:
        std = {}
    calibration = SensorCalibration(
        "acc",
        bias,
        matrix,
        "m/s^2",
        std,
        f"known orientations ({n_pos} positions, {weighting} weights)",
        covariance,
    )
    calibrated = errormodel.apply(matrix, bias, means)
    return KnownOrientationFit(
        calibration=calibration,
        labels=labels,
        position_means=means,
        directions=d,
        residuals_m_s2=calibrated - gravity_m_s2 * d,
        magnitude_error_m_s2=np.linalg.norm(calibrated, axis=1) - gravity_m_s2,
        residual_std_m_s2=float(np.sqrt(s2)),
        placement_std_rad=placement,
        dof=dof,
    )


@dataclass(frozen=True)
class HeldOutPositions:
    """Leave-one-position-out errors of the known-orientation fit, and what it predicts.

    Attributes
    ----------
    errors_m_s2 : ndarray, shape (n_pos, 3)
        ``K_(-i) (mean_i - o_(-i)) - g d_i`` with the fit on the other positions, m/s^2; NaN
        where that fit fails.
    z2 : ndarray, shape (n_pos,)
        ``e^T P^-1 e`` with ``P`` the covariance the held-out fit predicts for ``e``: its
        parameters' reported covariance at the position, the noise of ``mean_i`` and the
        fit's placement tilt across ``d_i``. Chi-square with 3 dof when the covariance is
        honest (mean 3, 95 % below 7.81).
    """

    errors_m_s2: np.ndarray
    z2: np.ndarray


def heldout_positions(
    positions: Sequence[np.ndarray],
    directions: np.ndarray,
    gravity_m_s2: float,
    *,
    weighting: str = "tilt",
) -> HeldOutPositions:
    """Each position against the known-orientation fit on the others.

    Parameters
    ----------
    positions, directions, gravity_m_s2, weighting
        As in :func:`fit_known_orientations`; each fit on the others needs at least
        ``MIN_POSITIONS + 1`` of them for standard deviations.

    Returns
    -------
    HeldOutPositions

    Raises
    ------
    ValueError
        With fewer than ``MIN_POSITIONS + 2`` positions.
    """
    n_pos = len(positions)
    if n_pos < MIN_POSITIONS + 2:
        raise ValueError(
            f"{n_pos} positions: leaving one out needs at least {MIN_POSITIONS + 2} (the fit on "
            f"the others needs {MIN_POSITIONS + 1} for its standard deviations)"
        )
    d = np.asarray(directions, dtype=float)
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    errors = np.full((n_pos, 3), np.nan)
    z2 = np.full(n_pos, np.nan)
    for i in range(n_pos):
        rest = [k for k in range(n_pos) if k != i]
        try:
            fit = fit_known_orientations(
                [positions[k] for k in rest], d[rest], gravity_m_s2, weighting=weighting
            )
        except ValueError:  # the others do not span 3-D
            continue
        cal = fit.calibration
        samples = np.asarray(positions[i], dtype=float)
        mean = samples.mean(axis=0)
        errors[i] = cal.matrix @ (mean - cal.bias) - gravity_m_s2 * d[i]
        parameters = uncertainty.calibrated_covariance(
            cal.matrix, cal.bias, cal.covariance, mean[None, :]
        )[0]
        noise = cal.matrix @ (np.cov(samples.T) / len(samples)) @ cal.matrix.T
        tilt = (fit.placement_std_rad * gravity_m_s2) ** 2 * (np.eye(3) - np.outer(d[i], d[i]))
        z2[i] = errors[i] @ np.linalg.solve(parameters + noise + tilt, errors[i])
    return HeldOutPositions(errors, z2)


# --------------------------------------------------------------------------------------------
# Gyroscope: rotations through known angles
# --------------------------------------------------------------------------------------------


def integrate_rate(t_s: np.ndarray, rate: np.ndarray) -> np.ndarray:
    """Trapezoidal integral of a rate over its own (possibly irregular) timestamps.

    Parameters
    ----------
    t_s : ndarray, shape (n,)
        Strictly increasing times, s.
    rate : ndarray, shape (n, 3)
        Rate, e.g. rad/s.

    Returns
    -------
    ndarray, shape (3,)
        Integral, e.g. rad.
    """
    t = np.asarray(t_s, dtype=float)
    dt = np.diff(t)
    return (0.5 * (rate[1:] + rate[:-1]) * dt[:, None]).sum(axis=0)


def _trapezoid_weights(t: np.ndarray) -> np.ndarray:
    dt = np.diff(t)
    w = np.zeros(len(t))
    w[1:] += 0.5 * dt
    w[:-1] += 0.5 * dt
    return w


def _check_times(t_s: np.ndarray, n: int, name: str) -> np.ndarray:
    t = np.asarray(t_s, dtype=float)
    if t.shape != (n,) or not np.all(np.isfinite(t)):
        raise ValueError(f"{name}: expected {n} finite timestamps in s, got shape {t.shape}")
    if np.any(np.diff(t) <= 0):
        raise ValueError(f"{name}: timestamps must increase strictly (s)")
    return t


@dataclass(frozen=True)
class KnownRotationFit:
    """Gyroscope calibration from rotations through known angles.

    Attributes
    ----------
    calibration : SensorCalibration
        ``matrix`` (3, 3) maps a bias-free raw rate to frame B; ``bias`` (3,) rad/s as given;
        ``std`` holds 'matrix', 'scale', 'xi_rad', 'alpha_rad' (and 'bias' if given).
    labels : tuple of str
    raw_angles_rad : ndarray, shape (n_rot, 3)
        Integral of ``raw - bias`` over each section, rad (sensor frame).
    known_angles_rad : ndarray, shape (n_rot, 3)
        Known rotation vector of each section in B, rad.
    residuals_rad : ndarray, shape (n_rot, 3)
        ``matrix @ raw_angle - known_angle`` (in-sample; identically zero for 3 sections, which
        determine the 9 entries exactly).
    durations_s : ndarray, shape (n_rot,)
    """

    calibration: SensorCalibration
    labels: tuple[str, ...]
    raw_angles_rad: np.ndarray
    known_angles_rad: np.ndarray
    residuals_rad: np.ndarray
    durations_s: np.ndarray


def fit_known_rotations(
    sections: Sequence[tuple[np.ndarray, np.ndarray]],
    known_angles_rad: np.ndarray,
    bias_rad_s: np.ndarray,
    *,
    noise_std_rad_s: np.ndarray | None = None,
    bias_std_rad_s: np.ndarray | None = None,
    labels: Sequence[str] | None = None,
) -> KnownRotationFit:
    """Fit the gyroscope matrix so that calibrated integrated angles equal the known ones.

    Parameters
    ----------
    sections : sequence of (t_s, gyr)
        Each rotation section: times ``t_s`` shape (n_j,) in s (irregular allowed) and raw
        gyroscope readings ``gyr`` shape (n_j, 3) in rad/s (a nominal sensitivity is enough).
        Each section should start and end at rest.
    known_angles_rad : ndarray, shape (n_rot, 3)
        Rotation vector of each section in frame B, rad (e.g. ``-2 pi e_x`` for a clockwise
        360-degree turn about x of B).
    bias_rad_s : ndarray, shape (3,)
        Gyroscope bias (e.g. from the static faces), rad/s.
    noise_std_rad_s : ndarray, shape (3,), optional
        White-noise std of one raw sample per axis, rad/s; with it (and ``bias_std_rad_s``) the
        matrix standard deviations are propagated from the integration noise.
    bias_std_rad_s : ndarray, shape (3,), optional
        Standard deviation of ``bias_rad_s``, rad/s (its error grows with each duration).
    labels : sequence of str, optional

    Returns
    -------
    KnownRotationFit

    Raises
    ------
    ValueError
        Fewer than 3 sections, bad shapes or timestamps, or raw / known angle vectors that do
        not span 3-D (rotations about fewer than three independent axes).

    Notes
    -----
    ``matrix @ Theta_raw = Theta_known`` (columns = sections) is solved by least squares,
    ``matrix = Theta_known Theta_raw^T (Theta_raw Theta_raw^T)^-1``; for three sections this is
    the exact inverse. The covariance of ``Theta_raw`` is ``sigma^2 sum(w_i^2)`` per section and
    axis (trapezoid weights ``w_i``, white noise) plus ``T_j T_l Cov(bias)`` between sections of
    durations ``T_j``, ``T_l``; it is propagated to the matrix to first order.
    """
    n_rot = len(sections)
    labels = tuple(labels) if labels is not None else tuple(f"r{i + 1:02d}" for i in range(n_rot))
    known = np.asarray(known_angles_rad, dtype=float)
    bias = np.asarray(bias_rad_s, dtype=float).reshape(3)
    if n_rot < 3:
        raise ValueError(
            f"known-rotation fit needs at least 3 rotation sections (9 unknowns, 3 equations "
            f"each), got {n_rot}"
        )
    if known.shape != (n_rot, 3) or len(labels) != n_rot:
        raise ValueError(
            f"{n_rot} sections need known_angles_rad of shape ({n_rot}, 3) and {n_rot} labels, "
            f"got {known.shape} and {len(labels)}"
        )
    raw = np.zeros((n_rot, 3))
    durations = np.zeros(n_rot)
    weights2 = np.zeros(n_rot)
    for j, ((t_s, gyr), lab) in enumerate(zip(sections, labels)):
        g = _check_samples(gyr, f"rotation {lab!r}")
        t = _check_times(t_s, len(g), f"rotation {lab!r}")
        raw[j] = integrate_rate(t, g - bias)
        durations[j] = t[-1] - t[0]
        weights2[j] = np.sum(_trapezoid_weights(t) ** 2)
    for name, theta in (("raw", raw), ("known", known)):
        sv = np.linalg.svd(theta, compute_uv=False)
        if sv[-1] < MIN_CONDITION * sv[0]:
            raise ValueError(
                f"the {name} angle vectors of {list(labels)} do not span 3-D (singular values "
                f"{np.degrees(sv).round(2).tolist()} deg); expected rotations about three "
                "independent axes"
            )

    def solve(theta_raw: np.ndarray) -> np.ndarray:
        t = theta_raw.reshape(n_rot, 3).T  # (3, n_rot)
        return known.T @ t.T @ np.linalg.inv(t @ t.T)

    matrix = solve(raw.ravel())
    _check_proper(matrix, "gyroscope", "the signs of known_angles_rad (clockwise is negative)")
    std: dict[str, np.ndarray] = {}
    covariance = None
    if noise_std_rad_s is not None:
        noise = np.asarray(noise_std_rad_s, dtype=float).reshape(3)
        cov_b = (
            np.diag(np.asarray(bias_std_rad_s, dtype=float).reshape(3) ** 2)
            if (bias_std_rad_s is not None)
            else np.zeros((3, 3))
        )
        cov_raw = np.kron(np.outer(durations, durations), cov_b)
        cov_raw += np.kron(np.diag(weights2), np.diag(noise**2))
        cov_m = _propagate(solve, raw.ravel(), cov_raw)
        std = {
            "matrix": np.sqrt(np.clip(np.diag(cov_m), 0, None)).reshape(3, 3),
            **_decomposition_std(matrix, cov_m),
        }
        if bias_std_rad_s is not None:
            std["bias"] = np.asarray(bias_std_rad_s, dtype=float).reshape(3)
            # the bias enters the matrix through cov_raw; its cross-covariance with the matrix:
            # d vec(K) / d o  =  d solve / d raw . d raw / d o  (raw = integral - o * duration)
            j_raw = uncertainty.numerical_jacobian(lambda t: solve(t).ravel(), raw.ravel())
            j_bias = -j_raw @ np.kron(durations[:, None], np.eye(3))
            cov_b = np.diag(std["bias"] ** 2)
            cov12 = uncertainty.bias_matrix_covariance(cov_b, cov_m, j_bias @ cov_b)
            covariance = uncertainty.calibration_covariance(bias, matrix, cov12)
            std = uncertainty.std_of(covariance)
    calibration = SensorCalibration(
        "gyr",
        bias,
        matrix,
        "rad/s",
        std,
        f"known rotation angles ({n_rot} sections)",
        covariance,
    )
    return KnownRotationFit(
        calibration=calibration,
        labels=labels,
        raw_angles_rad=raw,
        known_angles_rad=known,
        residuals_rad=raw @ matrix.T - known,
        durations_s=durations,
    )
