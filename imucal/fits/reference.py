"""Calibration against an orientation reference (motion capture, robot): the gyroscope, and
the magnetometer's alignment.

The model is the error model of eq. 11 seen from the reference's body::

    omega_body = K (m - o),   K = M^T U,   U = T_N S,

with ``m`` the gyroscope's readings (rad/s, nominal scale), ``M`` the mounting (reference body
-> B) and ``U`` upper triangular. Only ``K`` is observable (a rotation of B cannot be told from
the mounting), so B is fixed as the paper's convention for a sensor without a platform:
``T_R = I``, B's x axis along the gyroscope's x axis and its y axis in the x-y plane.

Both sides are noisy: the reference's orientations carry tracking noise, the gyroscope white
noise. A regression of the reference's finite-difference rate on the gyroscope's rate (or the
reverse) is then biased towards zero on the axes the motion excites little (errors in
variables: the noise of the regressor attenuates the slope). The fit therefore compares
*integrated rotations*: over windows of :data:`WINDOW_S` between two present reference samples,
the gyroscope's readings mapped by ``K (m - o)`` and integrated (the orientation itself, exact for
large rotations) against the reference's relative rotation ``q(a)* q(b)``. Integration averages
the gyroscope's noise, and the reference's noise enters once per window end instead of once per
sample interval divided by its length, so the errors in the regressor are small against the
rotation they are compared with; gaps of the reference inside a window are bridged by the
gyroscope. The parameters are ``(rotation vector of M, the six entries of U, o)``, found by
Gauss-Newton from the time alignment's mounting with the nominal scale and the given bias.

The standard deviations are the larger of the formal ones (residual variance times
``(J^T J)^-1``) and a delete-a-block jackknife over :data:`N_BLOCKS` contiguous blocks of windows
(linearised at the solution), so coloured errors show. An entry of ``U`` whose standard
deviation exceeds :data:`MAX_ENTRY_STD` is not determined by the motion (an axis it barely
turns about): it keeps its nominal value (1 on the diagonal, 0 off it), the fit is repeated
without it, and it is reported with that large standard deviation in ``held_nominal``; never a
confident wrong value. Windows whose residual exceeds :data:`OUTLIER_SIGMA` robust standard
deviations (motion-capture glitches at the edges of tracking gaps) are left out and counted.

The magnetometer, after its ellipsoid fit (step 1), reads the field's direction in its own
frame; carried into the reference's world through B (``R_t T_R m_t``) it must be one constant
direction in an undisturbed field. :func:`fit_mag_to_reference` finds ``T_R`` (the
magnetometer's step 2 against the reference instead of the platform's phases) and the world
field by alternating least squares, with a jackknife covariance.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from imucal.calibration import SensorCalibration
from imucal.orientation import (
    integrate_rates,
    interpolate_orientation,
    interval_means,
    quat_conjugate,
    quat_multiply,
    quat_to_rotvec,
)
from imucal.uncertainty import numerical_jacobian

#: Residuals beyond this many robust (MAD) standard deviations are outliers.
OUTLIER_SIGMA = 5.0
#: Contiguous blocks of the jackknife uncertainty.
N_BLOCKS = 10
#: Fewest windows the gyroscope fit accepts (twelve parameters, three residuals a window, and
#: ten jackknife blocks of at least two windows).
MIN_WINDOWS = 20
#: Fewest reference samples the magnetometer alignment accepts.
MIN_INTERVALS = 100
#: Length of the integration windows of the gyroscope fit, s: long enough that the rotation in
#: a window is large against the reference's noise at its two ends, short enough that a
#: two-minute session gives a hundred windows between tracking gaps.
WINDOW_S = 1.0
#: An entry of U (scale, non-orthogonality) determined less well than this is held at its
#: nominal value: 1 % of scale (0.6 deg of non-orthogonality) is the tolerance of a consumer
#: MEMS gyroscope's sensitivity (docs/plausibility.md), so a wider interval says nothing the
#: datasheet did not.
MAX_ENTRY_STD = 0.01
#: Gauss-Newton iterations at most, and the step (in parameter units) that ends them.
MAX_ITERATIONS = 20
STEP_TOLERANCE = 1e-10
#: Order of the parameters: the mounting's rotation vector, U's upper entries, the bias.
_UPPER = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)]
#: Names of the entries of U, for ``held_nominal``.
ENTRY_NAMES = ("s_x", "u_xy", "u_xz", "s_y", "u_yz", "s_z")


@dataclass(frozen=True)
class ReferenceGyroFit:
    """Gyroscope calibration from an orientation reference.

    Attributes
    ----------
    calibration : SensorCalibration
        ``U`` (upper triangular, ``T_R = I``) and the bias ``o``, rad/s.
    full_matrix : ndarray, shape (3, 3)
        ``K``: bias-free reading -> reference body frame.
    mounting : ndarray, shape (3, 3)
        ``M``: reference body -> B.
    mounting_rotvec_rad, mounting_std_rad : ndarray, shape (3,)
        Rotation vector of ``M`` and the standard deviation of each of its components.
    std_matrix : ndarray, shape (3, 3)
        Standard deviation of the entries of ``U`` (of a held entry: the full fit's).
    held_nominal : tuple of str
        Entries of ``U`` (:data:`ENTRY_NAMES`) held at their nominal value.
    residual_rms_rad : ndarray, shape (3,)
        RMS rotation residual per window, per axis of the reference body frame, rad.
    n_windows, n_outliers : int
        Windows used, and left out as outliers.
    window_s : float
    """

    calibration: SensorCalibration
    full_matrix: np.ndarray
    mounting: np.ndarray
    mounting_rotvec_rad: np.ndarray
    mounting_std_rad: np.ndarray
    std_matrix: np.ndarray
    held_nominal: tuple
    residual_rms_rad: np.ndarray
    n_windows: int
    n_outliers: int
    window_s: float

    def to_dict(self) -> dict:
        return {
            "calibration": self.calibration.to_dict(),
            "method": "integrated rotations over windows (Gauss-Newton, errors in both sides)",
            "full_matrix": self.full_matrix.tolist(),
            "mounting": {
                "convention": "omega_B = M omega_body (reference body -> B)",
                "matrix": self.mounting.tolist(),
                "rotvec_rad": self.mounting_rotvec_rad.tolist(),
                "angle_deg": float(np.degrees(np.linalg.norm(self.mounting_rotvec_rad))),
                "std_rad": self.mounting_std_rad.tolist(),
            },
            "std_matrix": self.std_matrix.tolist(),
            "held_nominal": list(self.held_nominal),
            "max_entry_std": MAX_ENTRY_STD,
            "residual_rms_rad": self.residual_rms_rad.tolist(),
            "n_windows": self.n_windows,
            "n_outliers": self.n_outliers,
            "window_s": self.window_s,
        }


@dataclass(frozen=True)
class _Windows:
    """One recording's windows: module samples and the reference's rotation over each window."""

    t: np.ndarray  # (n,) module times, s
    m: np.ndarray  # (n, 3) readings, rad/s
    a: np.ndarray  # (k,) window starts, module clock, s
    b: np.ndarray  # (k,) window ends
    rel: np.ndarray  # (k, 4) reference rotation body(b) -> body(a)


def _windows(
    t: np.ndarray, m: np.ndarray, tau: np.ndarray, quat: np.ndarray, window_s: float
) -> _Windows:
    """Non-overlapping windows of at least ``window_s`` between present reference samples,
    inside the module's samples and without a module gap; consecutive windows share no sample
    (so the reference noise at an end enters one window only)."""
    ok = np.all(np.isfinite(m), axis=1)
    t, m = t[ok], m[ok]
    present = np.flatnonzero(np.all(np.isfinite(quat), axis=1) & (tau >= t[0]) & (tau <= t[-1]))
    starts, ends = [], []
    j = 0
    while j < present.size:
        i = present[j]
        k = j + np.searchsorted(tau[present[j:]], tau[i] + window_s)
        if k >= present.size:
            break
        starts.append(i)
        ends.append(present[k])
        j = k + 1
    s, e = np.array(starts, dtype=int), np.array(ends, dtype=int)
    a, b = tau[s], tau[e]
    # a window the module has a gap in (a NaN interval mean) cannot be integrated
    keep = np.all(np.isfinite(interval_means(t, m, a, b)), axis=1) if s.size else s.astype(bool)
    s, e = s[keep], e[keep]
    rel = quat_multiply(quat_conjugate(quat[s]), quat[e])
    return _Windows(t, m, tau[s], tau[e], rel)


def _matrix(p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """K, U and the bias from the parameters."""
    u = np.zeros((3, 3))
    for value, (i, j) in zip(p[3:9], _UPPER):
        u[i, j] = value
    mounting = Rotation.from_rotvec(p[:3]).as_matrix()
    return mounting.T @ u, u, p[9:12]


def _residuals(p: np.ndarray, windows: Sequence[_Windows]) -> tuple[np.ndarray, np.ndarray]:
    """Rotation residuals (k, 3), rad, in the body frame at each window's end, and their
    Jacobian (k, 3, 12) with respect to the parameters (analytic in the rate, numerical in the
    map from the parameters to ``(K, c = -K o)``)."""
    k, _, bias = _matrix(p)
    # d(K, c)/dp: the rate K m + c is linear in (K, c)
    dtheta = numerical_jacobian(
        lambda q: np.concatenate([_matrix(q)[0].ravel(), -_matrix(q)[0] @ _matrix(q)[2]]), p
    )
    res, jac = [], []
    for w in windows:
        omega = (w.m - bias) @ k.T
        q = integrate_rates(w.t, omega)  # body(t) -> body(t_0)
        rot = Rotation.from_quat(q[:, [1, 2, 3, 0]]).as_matrix()  # (n, 3, 3)
        qa = interpolate_orientation(w.t, q, w.a)
        qb = interpolate_orientation(w.t, q, w.b)
        gyro = quat_multiply(quat_conjugate(qa), qb)
        res.append(quat_to_rotvec(quat_multiply(quat_conjugate(w.rel), gyro)))
        # a rate change d omega at t turns the end by R(b)^T R(t) d omega dt (body frame at b)
        # d omega / d K_ij = e_i m_j, d omega / d c_i = e_i: cumulative integrals of R(t) m_j
        weights = np.concatenate([w.m, np.ones((w.t.size, 1))], axis=1)  # (n, 4)
        integrand = rot[:, :, :, None] * weights[:, None, None, :]  # (n, 3, 3, 4)
        steps = np.diff(w.t)[:, None, None, None]
        area = np.concatenate(
            [np.zeros((1, 3, 3, 4)), np.cumsum(0.5 * (integrand[1:] + integrand[:-1]) * steps, 0)]
        )
        flat = area.reshape(w.t.size, -1)
        span = np.stack(
            [np.interp(w.b, w.t, col) - np.interp(w.a, w.t, col) for col in flat.T], axis=1
        ).reshape(-1, 3, 3, 4)  # (k, row of R, i, j)
        rb = Rotation.from_quat(qb[:, [1, 2, 3, 0]]).as_matrix()
        turned = np.einsum("kra,krij->kaij", rb, span)  # (k, 3, i, j): R(b)^T int R e_i m_j
        d_k = turned[:, :, :, :3].reshape(-1, 3, 9)  # columns K_ij, row-major
        d_c = turned[:, :, :, 3]  # columns c_i
        jac.append(np.concatenate([d_k, d_c], axis=2) @ dtheta)
    return np.vstack(res), np.concatenate(jac, axis=0)


def _solve(
    p: np.ndarray, windows: Sequence[_Windows], free: np.ndarray, keep: np.ndarray
) -> np.ndarray:
    """Gauss-Newton over the free parameters on the kept windows."""
    for _ in range(MAX_ITERATIONS):
        res, jac = _residuals(p, windows)
        a = jac[keep][:, :, free].reshape(-1, int(free.sum()))
        step, *_ = np.linalg.lstsq(a, -res[keep].ravel(), rcond=None)
        p = p.copy()
        p[free] += step
        if np.max(np.abs(step)) < STEP_TOLERANCE:
            break
    return p


def _covariance(
    res: np.ndarray, jac: np.ndarray, free: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Formal and delete-a-block jackknife covariance of the free parameters (linearised)."""
    n_free = int(free.sum())
    a = jac[:, :, free]
    info = np.einsum("kri,krj->ij", a, a)
    dof = max(res.size - n_free, 1)
    formal = float(np.sum(res**2)) / dof * np.linalg.pinv(info)
    deltas = []
    for block in np.array_split(np.arange(res.shape[0]), N_BLOCKS):
        ab = a[block].reshape(-1, n_free)
        deltas.append(np.linalg.pinv(info - ab.T @ ab) @ (ab.T @ res[block].ravel()))
    deltas = np.array(deltas)
    centred = deltas - deltas.mean(axis=0)
    return formal, (N_BLOCKS - 1) / N_BLOCKS * centred.T @ centred


def fit_gyro_to_reference(
    series: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]],
    mounting: np.ndarray,
    bias_rad_s: np.ndarray,
    *,
    window_s: float = WINDOW_S,
    fit_matrix: bool = True,
) -> ReferenceGyroFit:
    """Gyroscope matrix, bias and mounting from integrated rotations against the reference.

    Parameters
    ----------
    series : sequence of (t_s, gyr, tau_s, quat)
        Per recording: module times ``(n,)``, s; gyroscope readings ``(n, 3)``, rad/s (nominal
        scale, not bias-corrected; NaN rows are left out); the reference's sample times on the
        module clock ``(m,)``, s (after the time alignment); its orientations ``(m, 4)``, body
        -> world, scalar first, NaN rows in gaps.
    mounting : array_like, shape (3, 3)
        Starting mounting (reference body -> B), e.g. the time alignment's.
    bias_rad_s : array_like, shape (3,)
        Starting bias, rad/s.
    window_s : float
        Window length, s.
    fit_matrix : bool
        False: ``U`` held at the identity (the nominal matrix; only the bias and the mounting
        are fitted), the fallback a fitted matrix is compared with.

    Returns
    -------
    ReferenceGyroFit

    Raises
    ------
    ValueError
        On shapes, fewer than :data:`MIN_WINDOWS` windows, or a matrix that mirrors.
    """
    windows = []
    for t, m, tau, quat in series:
        t, m = np.asarray(t, dtype=float), np.asarray(m, dtype=float)
        tau, quat = np.asarray(tau, dtype=float), np.asarray(quat, dtype=float)
        if m.shape != (t.size, 3) or quat.shape != (tau.size, 4):
            raise ValueError(
                "expected module times (n,), readings (n, 3), reference times (m,) and "
                f"quaternions (m, 4), got {t.shape}, {m.shape}, {tau.shape}, {quat.shape}"
            )
        w = _windows(t, m, tau, quat, window_s)
        if w.a.size:
            windows.append(w)
    n = sum(w.a.size for w in windows)
    if n < MIN_WINDOWS:
        raise ValueError(
            f"{n} windows of {window_s:g} s between present reference samples; expected at "
            f"least {MIN_WINDOWS} (a longer recording, or fewer tracking gaps)"
        )
    rot = Rotation.from_matrix(np.asarray(mounting, dtype=float))
    p0 = np.concatenate([rot.as_rotvec(), [1, 0, 0, 1, 0, 1], np.asarray(bias_rad_s, float)])
    free = np.ones(12, dtype=bool)
    free[3:9] = fit_matrix
    keep = np.ones(n, dtype=bool)
    p = p0
    for _ in range(3):
        p = _solve(p, windows, free, keep)
        res, _ = _residuals(p, windows)
        sigma = 1.4826 * np.median(np.abs(res[keep] - np.median(res[keep], axis=0)), axis=0)
        new = np.all(np.abs(res) <= OUTLIER_SIGMA * np.maximum(sigma, 1e-12), axis=1)
        if np.array_equal(new, keep):
            break
        keep = new
    res, jac = _residuals(p, windows)
    formal, jack = _covariance(res[keep], jac[keep], free)
    std_full = np.zeros(12)
    std_full[free] = np.sqrt(np.maximum(np.diag(formal), np.diag(jack)))
    # entries of U the motion does not determine keep their nominal value
    held = (std_full[3:9] > MAX_ENTRY_STD) & fit_matrix
    std = std_full
    if held.any():
        free[3:9] = ~held
        p = p.copy()
        p[3:9][held] = np.array([1, 0, 0, 1, 0, 1], dtype=float)[held]
        p = _solve(p, windows, free, keep)
        res, jac = _residuals(p, windows)
        formal, jack = _covariance(res[keep], jac[keep], free)
        std = std_full.copy()
        std[free] = np.sqrt(np.maximum(np.diag(formal), np.diag(jack)))
    k, u, bias = _matrix(p)
    if np.linalg.det(k) <= 0:
        raise ValueError("the fitted matrix mirrors the axes; expected a right-handed reference")
    std_u = np.zeros((3, 3))
    for value, (i, j) in zip(std[3:9], _UPPER):
        std_u[i, j] = value
    calibration = SensorCalibration(
        "gyr",
        bias,
        u,
        "rad/s",
        {"bias": std[9:12], "matrix": std_u},
        "against the orientation reference, integrated rotations (T_R = I: B along the "
        "gyroscope's x, y in its x-y plane; the rotation to the reference is the mounting)",
    )
    mounting_matrix = Rotation.from_rotvec(p[:3]).as_matrix()
    return ReferenceGyroFit(
        calibration=calibration,
        full_matrix=k,
        mounting=mounting_matrix,
        mounting_rotvec_rad=p[:3].copy(),
        mounting_std_rad=std[:3],
        std_matrix=std_u,
        held_nominal=tuple(name for name, h in zip(ENTRY_NAMES, held | ~free[3:9]) if h),
        residual_rms_rad=np.sqrt(np.mean(res[keep] ** 2, axis=0)),
        n_windows=int(keep.sum()),
        n_outliers=int(n - keep.sum()),
        window_s=float(window_s),
    )


# --------------------------------------------------------------------------- magnetometer


@dataclass(frozen=True)
class ReferenceMagFit:
    """Magnetometer alignment from an orientation reference.

    Attributes
    ----------
    alpha_rad : ndarray, shape (3,)
        Rotation vector of ``T_R``: the ellipsoid-fitted field (step 1) -> B.
    alpha_covariance : ndarray, shape (3, 3)
        Its covariance (delete-a-block jackknife).
    field_world : ndarray, shape (3,)
        The field's unit direction in the reference's world.
    residual_median_deg, residual_p95_deg : float
        Angles between each sample's field carried into the world and ``field_world``.
    n_samples : int
    """

    alpha_rad: np.ndarray
    alpha_covariance: np.ndarray
    field_world: np.ndarray
    residual_median_deg: float
    residual_p95_deg: float
    n_samples: int

    def to_dict(self) -> dict:
        return {
            "alpha_rad": self.alpha_rad.tolist(),
            "alpha_std_rad": np.sqrt(np.diag(self.alpha_covariance)).tolist(),
            "alpha_covariance": self.alpha_covariance.tolist(),
            "field_world": self.field_world.tolist(),
            "residual_median_deg": self.residual_median_deg,
            "residual_p95_deg": self.residual_p95_deg,
            "n_samples": self.n_samples,
        }


def _align_field(field: np.ndarray, to_world: Rotation, iterations: int = 50) -> tuple:
    """``T_R`` and the world field making ``to_world (T_R field)`` one constant direction.

    Alternates the two least-squares steps of ``sum |m_w - R_t T field_t|^2``: the world field
    as the mean of the carried directions, then ``T`` by Wahba against ``R_t^T m_w``.
    """
    unit = field / np.linalg.norm(field, axis=1, keepdims=True)
    rotation = Rotation.identity()
    for _ in range(iterations):
        carried = to_world.apply(rotation.apply(unit))
        world = carried.mean(axis=0)
        world /= np.linalg.norm(world)
        previous = rotation
        rotation, _ = Rotation.align_vectors(to_world.apply(world, inverse=True), unit)
        if (rotation * previous.inv()).magnitude() < 1e-10:
            break
    return rotation, world


def fit_mag_to_reference(
    field: np.ndarray, body_to_world: Rotation, frame_covariance: np.ndarray | None = None
) -> ReferenceMagFit:
    """``T_R`` of the magnetometer from an orientation reference: the field constant in its world.

    Parameters
    ----------
    field : ndarray, shape (n, 3)
        The magnetometer after its ellipsoid fit (step 1; any norm), at the reference's samples.
    body_to_world : Rotation
        ``n`` orientations of B in the reference's world (the reference's orientation times the
        inverse mounting).
    frame_covariance : ndarray, shape (3, 3), optional
        Covariance of a small rotation of B itself (the mounting's uncertainty): B is where the
        magnetometer is aligned to, so it adds to ``T_R``'s.

    Returns
    -------
    ReferenceMagFit

    Raises
    ------
    ValueError
        With fewer than :data:`MIN_INTERVALS` samples, or orientations that do not turn the field
        about two axes (the alignment is then not determined).
    """
    field = np.asarray(field, dtype=float)
    n = len(field)
    if n < MIN_INTERVALS:
        raise ValueError(
            f"{n} magnetometer samples with the reference; expected at least {MIN_INTERVALS}"
        )
    rotation, world = _align_field(field, body_to_world)
    # the field seen from B: it must sweep more than a cone about one axis
    seen = body_to_world.apply(world, inverse=True)
    spread = np.linalg.svd(seen - seen.mean(axis=0), compute_uv=False) / np.sqrt(n)
    if spread[1] < 0.05:
        raise ValueError(
            f"the field seen from B turns about one axis only (spread {spread.tolist()}); "
            "expected rotations about at least two axes"
        )
    blocks = np.array_split(np.arange(n), N_BLOCKS)
    jack = []
    for block in blocks:
        keep = np.setdiff1d(np.arange(n), block)
        r_k, _ = _align_field(field[keep], body_to_world[keep])
        jack.append((r_k * rotation.inv()).as_rotvec())
    jack = np.array(jack)
    centred = jack - jack.mean(axis=0)
    # the jackknife of a small rotation of B, carried to the rotation vector alpha (which may be
    # far from zero: a magnetometer mounted with swapped axes)
    small = (N_BLOCKS - 1) / N_BLOCKS * centred.T @ centred
    if frame_covariance is not None:
        small = small + np.asarray(frame_covariance, dtype=float)
    to_alpha = numerical_jacobian(
        lambda d: (Rotation.from_rotvec(d) * rotation).as_rotvec(), np.zeros(3)
    )
    covariance = to_alpha @ small @ to_alpha.T
    unit = field / np.linalg.norm(field, axis=1, keepdims=True)
    carried = body_to_world.apply(rotation.apply(unit))
    angles = np.degrees(np.arccos(np.clip(carried @ world, -1.0, 1.0)))
    return ReferenceMagFit(
        rotation.as_rotvec(),
        covariance,
        world,
        float(np.median(angles)),
        float(np.percentile(angles, 95)),
        n,
    )
