"""Gyroscope calibration from the gravity direction at consecutive static poses.

The method of Tedaldi, Pretto & Menegatti (ICRA 2014), used by imu_tk: the module is put down by
hand in many static poses. The calibrated accelerometer gives the direction of gravity (the
specific force, "up") at each pose in frame B. Between two poses the calibrated gyroscope rate,
integrated over the handling, must carry the direction seen at pose ``k`` into the direction seen
at pose ``k + 1``. The 9 parameters of the gyroscope matrix (scale, non-orthogonality ``xi`` and
rotation ``alpha`` of :func:`imucal.errormodel.compose`) minimise the mismatch; the bias is fixed
(from an initial static interval), as in the paper.

Orientation convention: ``R`` maps B to the world, ``dR/dt = R [omega]_x`` with the body rate
``omega``; a world-fixed vector seen in B at the end of an interval is ``dR^T v_start`` with
``dR = prod_i exp([omega_i dt_i]_x)`` (increments multiplied on the right, in time order).

References
----------
Tedaldi, Pretto, Menegatti, "A robust and easy to implement method for IMU calibration without
external equipments", IEEE ICRA 2014, pp. 3042-3049.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from imucal import errormodel, uncertainty
from imucal.calibration import SensorCalibration
from imucal.columns import AXES

#: 9 unknowns and two independent equations per interval (a direction has 2 degrees of freedom).
MIN_INTERVALS = 5
#: Smallest accepted ``sqrt(lambda_min / lambda_max)`` of the rotation-axis excitation.
MIN_EXCITATION_RATIO = 0.05
#: Smallest accepted ratio of the smallest to the largest Jacobian singular value.
MIN_JACOBIAN_RATIO = 1e-6
PARAMETER_NAMES = tuple(f"{p}_{a}" for p in ("scale", "xi", "alpha") for a in AXES)


def _quat_multiply(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product of scalar-last quaternions, shapes (..., 4)."""
    pv, pw = p[..., :3], p[..., 3:]
    qv, qw = q[..., :3], q[..., 3:]
    vec = pw * qv + qw * pv + np.cross(pv, qv)
    w = pw * qw - np.sum(pv * qv, axis=-1, keepdims=True)
    return np.concatenate([vec, w], axis=-1)


def _quat_exp(rotvec: np.ndarray) -> np.ndarray:
    """Scalar-last quaternion of rotation vectors, shape (..., 3) -> (..., 4)."""
    angle = np.linalg.norm(rotvec, axis=-1, keepdims=True)
    # sin(angle / 2) / angle = 0.5 sinc(angle / (2 pi)), finite at 0
    return np.concatenate([0.5 * np.sinc(angle / (2 * np.pi)) * rotvec, np.cos(angle / 2)], -1)


def _product_in_order(quats: np.ndarray) -> np.ndarray:
    """``q_0 q_1 ... q_{L-1}`` along axis 1 of shape (n, L, 4) by pairwise reduction."""
    q = quats
    while q.shape[1] > 1:
        if q.shape[1] % 2:
            identity = np.zeros((q.shape[0], 1, 4))
            identity[..., 3] = 1.0
            q = np.concatenate([q, identity], axis=1)
        q = _quat_multiply(q[:, 0::2], q[:, 1::2])
    return q[:, 0]


def _check_directions(values: np.ndarray, n: int, name: str) -> np.ndarray:
    d = np.asarray(values, dtype=float)
    if d.shape != (n, 3) or not np.all(np.isfinite(d)):
        raise ValueError(f"{name}: expected {n} finite directions of shape ({n}, 3), got {d.shape}")
    norms = np.linalg.norm(d, axis=1)
    if np.any(norms < 1e-9):
        raise ValueError(f"{name}: direction {int(np.argmin(norms))} is zero")
    return d / norms[:, None]


def _raw_increments(
    intervals: Sequence[tuple[np.ndarray, np.ndarray]], bias: np.ndarray
) -> np.ndarray:
    """Bias-free raw angle increments per step, padded with zeros: shape (n_int, L, 3), rad.

    Step ``i`` of an interval uses the mean of the rates at its two ends times the actual
    ``dt_i`` (irregular timestamps allowed).
    """
    steps = []
    for k, (t_s, rate) in enumerate(intervals):
        r = np.asarray(rate, dtype=float)
        t = np.asarray(t_s, dtype=float)
        if r.ndim != 2 or r.shape[1] != 3 or len(r) < 2:
            raise ValueError(f"interval {k}: rate must have shape (n, 3), n >= 2; got {r.shape}")
        if t.shape != (len(r),) or not np.all(np.isfinite(t)) or not np.all(np.isfinite(r)):
            raise ValueError(
                f"interval {k}: expected {len(r)} finite timestamps (s) and finite rates, "
                f"got timestamps of shape {t.shape}"
            )
        dt = np.diff(t)
        if np.any(dt <= 0):
            raise ValueError(f"interval {k}: timestamps must increase strictly (s)")
        centred = r - bias
        steps.append(0.5 * (centred[1:] + centred[:-1]) * dt[:, None])
    out = np.zeros((len(steps), max(len(s) for s in steps), 3))
    for k, s in enumerate(steps):
        out[k, : len(s)] = s
    return out


def _carry(increments: np.ndarray, matrix: np.ndarray, start: np.ndarray) -> np.ndarray:
    """Start directions carried to the end of each interval with ``matrix``, shape (n_int, 3)."""
    delta = _product_in_order(_quat_exp(increments @ matrix.T))
    return Rotation.from_quat(delta).apply(start, inverse=True)


def _angles_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    # atan2 of |cross| and dot: accurate for small and large angles alike
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.sum(a * b, axis=1)))


def gravity_direction_errors(
    start_directions: np.ndarray,
    end_directions: np.ndarray,
    intervals: Sequence[tuple[np.ndarray, np.ndarray]],
    matrix: np.ndarray | None = None,
    bias_rad_s: np.ndarray | None = None,
) -> np.ndarray:
    """Angle between the carried and the measured gravity direction for each interval.

    Parameters
    ----------
    start_directions : ndarray, shape (n_int, 3)
        Gravity (up) direction in frame B at the pose before each interval (normalised here).
    end_directions : ndarray, shape (n_int, 3)
        Gravity direction in B measured at the pose after each interval.
    intervals : sequence of (t_s, rate)
        Per interval: times ``t_s`` shape (m,) in s, strictly increasing (irregular allowed),
        and gyroscope readings ``rate`` shape (m, 3) in rad/s covering the handling from the
        end of the first pose to the start of the next.
    matrix : ndarray, shape (3, 3), optional
        Gyroscope matrix; default identity (``rate`` is already calibrated, e.g. by another
        tool's model).
    bias_rad_s : ndarray, shape (3,), optional
        Gyroscope bias; default zero.

    Returns
    -------
    ndarray, shape (n_int,)
        Angle errors, degrees.
    """
    n = len(intervals)
    if n == 0:
        raise ValueError("no intervals given; expected at least one (t_s, rate) pair")
    start = _check_directions(start_directions, n, "start_directions")
    end = _check_directions(end_directions, n, "end_directions")
    m = np.eye(3) if matrix is None else np.asarray(matrix, dtype=float).reshape(3, 3)
    b = np.zeros(3) if bias_rad_s is None else np.asarray(bias_rad_s, dtype=float).reshape(3)
    return _angles_deg(_carry(_raw_increments(intervals, b), m, start), end)


@dataclass(frozen=True)
class PoseToPoseFit:
    """Gyroscope calibration from pose-to-pose gravity directions.

    Attributes
    ----------
    calibration : SensorCalibration
        Gyroscope ``matrix`` (3, 3) to frame B (the accelerometer's frame) and the given
        ``bias`` (rad/s); ``std`` holds 'matrix', 'scale', 'xi_rad', 'alpha_rad'.
    angle_errors_before_deg : ndarray, shape (n_int,)
        Per-interval gravity-direction error with the initial matrix, degrees.
    angle_errors_deg : ndarray, shape (n_int,)
        The same with the fitted matrix (in-sample), degrees.
    parameters : ndarray, shape (9,)
        ``(scale, xi_rad, alpha_rad)`` of the fitted matrix (see :data:`PARAMETER_NAMES`).
    parameter_std : ndarray, shape (9,)
        Their standard deviations from the Jacobian, scaled by the residual variance.
    residual_std_rad : float
        RMS direction residual per degree of freedom (2 per interval), rad.
    singular_values : ndarray, shape (9,)
        Singular values of the Jacobian at the solution, largest first.
    excitation_rad : ndarray, shape (3,)
        Total raw rotation angle turned about each sensor axis over all intervals, rad.
    dof : int
        ``2 n_int - 9``.
    """

    calibration: SensorCalibration
    angle_errors_before_deg: np.ndarray
    angle_errors_deg: np.ndarray
    parameters: np.ndarray
    parameter_std: np.ndarray
    residual_std_rad: float
    singular_values: np.ndarray
    excitation_rad: np.ndarray
    dof: int


def _excitation_check(increments: np.ndarray) -> np.ndarray:
    """Refuse rotations that leave an axis direction unexcited; return the angle per axis."""
    u = increments.reshape(-1, 3)
    angle = np.linalg.norm(u, axis=1)
    moving = angle > 0
    axes = u[moving] / angle[moving, None]
    # angle-weighted scatter of the rotation axes
    scatter = (axes * angle[moving, None]).T @ axes
    lam, vec = np.linalg.eigh(scatter)
    if lam[-1] <= 0:
        raise ValueError("the gyroscope shows no rotation in any interval; expected handling")
    ratio = np.sqrt(max(lam[0], 0.0) / lam[-1])
    if ratio < MIN_EXCITATION_RATIO:
        weak = vec[:, 0] * np.sign(vec[np.argmax(np.abs(vec[:, 0])), 0])
        axis = AXES[int(np.argmax(np.abs(weak)))]
        raise ValueError(
            "the gyroscope matrix is not observable: the rotations between poses hardly turn "
            f"about the sensor direction {weak.round(3).tolist()} (near axis {axis!r}; "
            f"excitation ratio {ratio:.3g}, need >= {MIN_EXCITATION_RATIO}); expected rotations "
            "about all three axes"
        )
    return np.abs(u).sum(axis=0)


def fit_pose_to_pose(
    start_directions: np.ndarray,
    end_directions: np.ndarray,
    intervals: Sequence[tuple[np.ndarray, np.ndarray]],
    bias_rad_s: np.ndarray,
    *,
    initial_matrix: np.ndarray | None = None,
    bias_std_rad_s: np.ndarray | None = None,
    direction_covariance: np.ndarray | None = None,
) -> PoseToPoseFit:
    """Fit the gyroscope matrix to the gravity-direction change between static poses.

    Parameters
    ----------
    start_directions : ndarray, shape (n_int, 3)
        Gravity (up) direction at the pose before each interval in frame B, from the calibrated
        accelerometer mean at that pose (normalised here). For a chain of poses pass
        ``directions[:-1]``.
    end_directions : ndarray, shape (n_int, 3)
        Gravity direction at the pose after each interval (``directions[1:]`` for a chain).
    intervals : sequence of (t_s, gyr)
        Per interval: times ``t_s`` shape (m,) in s (irregular allowed) and raw gyroscope
        readings ``gyr`` shape (m, 3) in rad/s from the end of one pose to the start of the
        next.
    bias_rad_s : ndarray, shape (3,)
        Gyroscope bias (e.g. from the initial static interval), rad/s, held fixed.
    initial_matrix : ndarray, shape (3, 3), optional
        Starting matrix (positive determinant); default identity (readings in nominal rad/s).
    bias_std_rad_s : ndarray, shape (3,), optional
        Standard deviation of ``bias_rad_s``; with it the calibration carries the covariance of
        its 21 parameters, the bias's effect on the fitted matrix included (a bias error turns
        every interval's increment the same way).
    direction_covariance : ndarray, shape (6 n_int, 6 n_int), optional
        Covariance of ``(start_directions.ravel(), end_directions.ravel())`` from an error
        common to all of them (the accelerometer calibration that gave them). Such an error is
        largely absorbed by the fitted matrix, so the residuals do not show it; it is carried
        to the parameters like the bias's (``d theta / d directions`` at the solution).

    Returns
    -------
    PoseToPoseFit

    Raises
    ------
    ValueError
        Fewer than 5 intervals, bad shapes or timestamps, rotations that leave a direction
        unexcited (names the weak sensor axis), or a Jacobian too ill-conditioned to
        determine the 9 parameters (names the weakest parameter).

    Notes
    -----
    Residual of interval ``k``: ``g_{k+1} - dR_k(M)^T g_k`` (3 components of a difference of unit
    vectors, about the angle error in rad; 2 of them independent). Each step of the
    integration is the exact exponential map of ``M (mean raw rate - bias) dt`` (second-order
    accurate in ``dt``, like the RK4 integration of Tedaldi et al. for smooth handling), minimised
    with ``scipy.optimize.least_squares`` (trust-region reflective, 2-point Jacobian). The
    parameter covariance is ``s^2 (J^T J)^-1`` with ``s^2 = RSS / (2 n_int - 9)``: it reflects
    the scatter actually seen (accelerometer direction errors, integration and bias errors), not
    a noise model.
    """
    n = len(intervals)
    if n < MIN_INTERVALS:
        raise ValueError(
            f"pose-to-pose fit needs at least {MIN_INTERVALS} intervals between static poses "
            f"(9 unknowns, 2 equations each), got {n}"
        )
    start = _check_directions(start_directions, n, "start_directions")
    end = _check_directions(end_directions, n, "end_directions")
    bias = np.asarray(bias_rad_s, dtype=float).reshape(3)
    m0 = np.eye(3) if initial_matrix is None else np.asarray(initial_matrix, dtype=float)
    d0 = errormodel.decompose(m0)
    increments = _raw_increments(intervals, bias)
    excitation = _excitation_check(increments)

    def matrix_of(theta: np.ndarray) -> np.ndarray:
        return errormodel.compose(theta[:3], theta[3:6], theta[6:])

    def residuals(theta: np.ndarray) -> np.ndarray:
        return (end - _carry(increments, matrix_of(theta), start)).ravel()

    theta0 = np.concatenate([d0.scale, d0.xi_rad, d0.alpha_rad])
    sol = least_squares(residuals, theta0, method="trf", x_scale="jac")
    theta = sol.x
    jac = sol.jac
    sv = np.linalg.svd(jac, compute_uv=False)
    if sv[-1] < MIN_JACOBIAN_RATIO * sv[0]:
        _, _, vt = np.linalg.svd(jac)
        weakest = PARAMETER_NAMES[int(np.argmax(np.abs(vt[-1])))]
        raise ValueError(
            f"the {n} intervals do not determine the gyroscope matrix: Jacobian singular values "
            f"{sv[-1]:.3g} vs {sv[0]:.3g}, weakest parameter {weakest!r}; expected rotations "
            "that tilt gravity about all three axes"
        )
    dof = 2 * n - 9
    rss = float(np.sum(sol.fun**2))
    s2 = rss / dof if dof > 0 else np.nan
    cov = s2 * np.linalg.inv(jac.T @ jac)
    matrix = matrix_of(theta)
    if direction_covariance is not None:
        c_dir = np.asarray(direction_covariance, dtype=float)
        if c_dir.shape != (6 * n, 6 * n) or not np.all(np.isfinite(c_dir)):
            raise ValueError(
                f"direction_covariance must be a finite ({6 * n}, {6 * n}) matrix over the "
                f"start and end directions of {n} intervals, got shape {c_dir.shape}"
            )
        # implicit function theorem, as for the bias: d theta / d d = -(J^T J)^-1 J^T dr / d d
        dr_dd = uncertainty.numerical_jacobian(
            lambda d: (
                d[3 * n :].reshape(n, 3) - _carry(increments, matrix, d[: 3 * n].reshape(n, 3))
            ).ravel(),
            np.concatenate([start.ravel(), end.ravel()]),
        )
        to_theta = -np.linalg.solve(jac.T @ jac, jac.T @ dr_dd)
        cov = cov + to_theta @ c_dir @ to_theta.T

    # matrix-entry covariance by first-order propagation through compose
    step = 1e-7
    jm = np.zeros((9, 9))
    for i in range(9):
        dx = np.zeros(9)
        dx[i] = step
        jm[:, i] = (matrix_of(theta + dx) - matrix_of(theta - dx)).ravel() / (2 * step)
    std_theta = np.sqrt(np.clip(np.diag(cov), 0, None))
    std = {
        "matrix": np.sqrt(np.clip(np.diag(jm @ cov @ jm.T), 0, None)).reshape(3, 3),
        "scale": std_theta[:3],
        "xi_rad": std_theta[3:6],
        "alpha_rad": std_theta[6:],
    }
    covariance = None
    if bias_std_rad_s is not None:
        # a bias error turns every interval's increment and so the fitted matrix: by the
        # implicit function theorem d theta / d o = -(J^T J)^-1 J^T d r / d o
        dr_db = uncertainty.numerical_jacobian(
            lambda b: (end - _carry(_raw_increments(intervals, b), matrix, start)).ravel(), bias
        )
        to_matrix = jm @ -np.linalg.solve(jac.T @ jac, jac.T @ dr_db)  # d vec(K) / d o, (9, 3)
        cov_b = np.diag(np.asarray(bias_std_rad_s, dtype=float).reshape(3) ** 2)
        cov12 = uncertainty.bias_matrix_covariance(
            cov_b, jm @ cov @ jm.T + to_matrix @ cov_b @ to_matrix.T, to_matrix @ cov_b
        )
        covariance = uncertainty.calibration_covariance(bias, matrix, cov12)
        std = uncertainty.std_of(covariance)
    calibration = SensorCalibration(
        "gyr",
        bias,
        matrix,
        "rad/s",
        std,
        f"pose-to-pose gravity directions ({n} intervals)",
        covariance,
    )
    return PoseToPoseFit(
        calibration=calibration,
        angle_errors_before_deg=_angles_deg(_carry(increments, m0, start), end),
        angle_errors_deg=_angles_deg(_carry(increments, matrix, start), end),
        parameters=theta,
        parameter_std=std_theta,
        residual_std_rad=float(np.sqrt(s2)),
        singular_values=sv,
        excitation_rad=excitation,
        dof=dof,
    )
