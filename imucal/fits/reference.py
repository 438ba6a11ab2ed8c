"""Calibration against an orientation reference (motion capture, robot): the gyroscope, and
the magnetometer's alignment.

The reference's relative rotation over each of its sample intervals, divided by the interval,
is the mean body rate ``omega_body`` there (:func:`imucal.orientation.body_rates`); the
gyroscope's readings averaged over the same interval (on the module clock, after the time
alignment) are ``m``. The model is the error model of eq. 11 seen from the reference's body::

    omega_body = K (m - o),   K = M^T T_R T_N S,

with ``M`` the mounting (reference body -> B). Only ``K`` is observable (a rotation of B
cannot be told from the mounting), so B is fixed as the paper's convention for a sensor without
a platform: ``T_R = I``, B's x axis along the gyroscope's x axis and its y axis in the x-y
plane. Then ``K = Q U`` (QR, positive diagonal) gives the calibration matrix ``U = T_N S``
(upper triangular) and the mounting ``M = Q^T``, each with its uncertainty.

``K`` and ``c = -K o`` are a linear least-squares fit, three independent regressions on
``[m, 1]``. Samples whose residual exceeds :data:`OUTLIER_SIGMA` robust standard deviations
(motion-capture glitches at the edges of tracking gaps) are left out and counted. The
finite-difference rates have coloured errors, so the standard deviations are the larger of the
formal ones and the delete-a-block jackknife's over :data:`N_BLOCKS` contiguous blocks.

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

from imucal import errormodel
from imucal.calibration import SensorCalibration
from imucal.uncertainty import numerical_jacobian

#: Residuals beyond this many robust (MAD) standard deviations are outliers.
OUTLIER_SIGMA = 5.0
#: Contiguous blocks of the jackknife uncertainty.
N_BLOCKS = 10
#: Fewest intervals the fit accepts (twelve parameters, and every axis must be excited).
MIN_INTERVALS = 100
#: Smallest singular value of the normalised design accepted: below it an axis is not excited.
MIN_EXCITATION = 1e-3


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
        ``M = Q^T``: reference body -> B.
    mounting_rotvec_rad, mounting_std_rad : ndarray, shape (3,)
        Rotation vector of ``M`` and the standard deviation of a small rotation about each axis
        of B.
    std_matrix : ndarray, shape (3, 3)
        Standard deviation of the entries of ``U``.
    residual_rms_rad_s : ndarray, shape (3,)
        RMS residual per axis of the reference body frame.
    n_intervals, n_outliers : int
        Intervals used, and left out as outliers.
    """

    calibration: SensorCalibration
    full_matrix: np.ndarray
    mounting: np.ndarray
    mounting_rotvec_rad: np.ndarray
    mounting_std_rad: np.ndarray
    std_matrix: np.ndarray
    residual_rms_rad_s: np.ndarray
    n_intervals: int
    n_outliers: int

    def to_dict(self) -> dict:
        return {
            "calibration": self.calibration.to_dict(),
            "full_matrix": self.full_matrix.tolist(),
            "mounting": {
                "convention": "omega_B = M omega_body (reference body -> B)",
                "matrix": self.mounting.tolist(),
                "rotvec_rad": self.mounting_rotvec_rad.tolist(),
                "angle_deg": float(np.degrees(np.linalg.norm(self.mounting_rotvec_rad))),
                "std_rad": self.mounting_std_rad.tolist(),
            },
            "std_matrix": self.std_matrix.tolist(),
            "residual_rms_rad_s": self.residual_rms_rad_s.tolist(),
            "n_intervals": self.n_intervals,
            "n_outliers": self.n_outliers,
        }


def _solve(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Least squares ``y = x theta``; returns theta (4, 3) and (x^T x)^-1."""
    theta, *_ = np.linalg.lstsq(x, y, rcond=None)
    return theta, np.linalg.pinv(x.T @ x)


def _factor(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """K, bias, U and M from the stacked parameters (rows 0-2: K^T, row 3: c)."""
    k = theta[:3].T
    bias = -np.linalg.solve(k, theta[3])
    q, u = errormodel.upper_triangular_factor(k)
    return k, bias, u, q.T


def fit_gyro_to_reference(
    readings: Sequence[np.ndarray], body_rates: Sequence[np.ndarray]
) -> ReferenceGyroFit:
    """Gyroscope matrix and bias from interval-mean readings and the reference's body rates.

    Parameters
    ----------
    readings : sequence of ndarray, shape (n_i, 3)
        Per recording, the gyroscope readings (rad/s, nominal scale, not bias-corrected)
        averaged over each reference interval, on the module clock
        (:func:`imucal.orientation.interval_means`); NaN rows are left out.
    body_rates : sequence of ndarray, shape (n_i, 3)
        The reference's body rates over the same intervals, rad/s.

    Returns
    -------
    ReferenceGyroFit

    Raises
    ------
    ValueError
        On shapes, fewer than :data:`MIN_INTERVALS` intervals, an axis not excited, or a
        matrix that mirrors (a reference in the wrong handedness).
    """
    if len(readings) != len(body_rates) or not readings:
        raise ValueError("expected one body-rate array per readings array, at least one")
    xs, ys = [], []
    for m, w in zip(readings, body_rates):
        m, w = np.asarray(m, dtype=float), np.asarray(w, dtype=float)
        if m.ndim != 2 or m.shape[1] != 3 or w.shape != m.shape:
            raise ValueError(
                f"expected readings and rates of equal shape (n, 3), got {m.shape}, {w.shape}"
            )
        ok = np.all(np.isfinite(m), axis=1) & np.all(np.isfinite(w), axis=1)
        xs.append(m[ok])
        ys.append(w[ok])
    m_all, w_all = np.vstack(xs), np.vstack(ys)
    n = m_all.shape[0]
    if n < MIN_INTERVALS:
        raise ValueError(f"{n} intervals with both rates; expected at least {MIN_INTERVALS}")
    x = np.column_stack([m_all, np.ones(n)])
    scaled = (m_all - m_all.mean(axis=0)) / max(np.sqrt(np.mean(m_all**2)), 1e-300)
    sv = np.linalg.svd(scaled / np.sqrt(n), compute_uv=False)
    if sv.min() < MIN_EXCITATION * sv.max():
        raise ValueError(
            f"the motion excites the gyroscope's axes unevenly (singular values {sv.tolist()}); "
            "expected rotations about every axis"
        )
    keep = np.ones(n, dtype=bool)
    for _ in range(3):
        theta, _ = _solve(x[keep], w_all[keep])
        res = w_all - x @ theta
        sigma = 1.4826 * np.median(np.abs(res[keep] - np.median(res[keep], axis=0)), axis=0)
        new = np.all(np.abs(res) <= OUTLIER_SIGMA * np.maximum(sigma, 1e-12), axis=1)
        if np.array_equal(new, keep):
            break
        keep = new
    theta, inv = _solve(x[keep], w_all[keep])
    res = (w_all - x @ theta)[keep]
    k, bias, u, mounting = _factor(theta)
    if np.linalg.det(k) <= 0:
        raise ValueError("the fitted matrix mirrors the axes; expected a right-handed reference")
    # formal covariance per output axis: var_i (x^T x)^-1
    dof = max(res.shape[0] - 4, 1)
    var = np.sum(res**2, axis=0) / dof
    # delete-a-block jackknife: each fit leaves one contiguous block out, so every fit is as
    # well excited as the whole and the blocks' coloured errors show in the spread
    idx = np.flatnonzero(keep)
    samples = []
    for part in np.array_split(idx, N_BLOCKS):
        rest = np.setdiff1d(idx, part, assume_unique=True)
        samples.append(_derived(_solve(x[rest], w_all[rest])[0]))
    spread = np.sqrt((N_BLOCKS - 1) * np.var(np.array(samples), axis=0))
    formal_derived = _propagate(theta, inv, var)
    std = np.maximum(spread, formal_derived)
    std_u = std[:9].reshape(3, 3) * (np.triu(np.ones((3, 3))) > 0)
    std_bias = std[9:12]
    std_mount = std[12:15]
    calibration = SensorCalibration(
        "gyr",
        bias,
        u,
        "rad/s",
        {"bias": std_bias, "matrix": std_u},
        "against the orientation reference (T_R = I: B along the gyroscope's x, y in its x-y "
        "plane; the rotation to the reference is the mounting)",
    )
    return ReferenceGyroFit(
        calibration=calibration,
        full_matrix=k,
        mounting=mounting,
        mounting_rotvec_rad=Rotation.from_matrix(mounting).as_rotvec(),
        mounting_std_rad=std_mount,
        std_matrix=std_u,
        residual_rms_rad_s=np.sqrt(np.mean(res**2, axis=0)),
        n_intervals=int(keep.sum()),
        n_outliers=int(n - keep.sum()),
    )


def _derived(theta: np.ndarray) -> np.ndarray:
    """U (9), bias (3) and the mounting as a small rotation about the fitted one (3)."""
    _, bias, u, mounting = _factor(theta)
    return np.concatenate([u.ravel(), bias, Rotation.from_matrix(mounting).as_rotvec()])


def _propagate(theta: np.ndarray, inv: np.ndarray, var: np.ndarray) -> np.ndarray:
    """First-order standard deviations of :func:`_derived` (mounting as a small rotation about
    the fitted one): column ``j`` of theta has covariance ``var[j] inv``, columns independent."""
    base = _derived(theta)
    mounting = Rotation.from_rotvec(base[12:15]).as_matrix()
    cov = np.zeros((base.size, base.size))
    for j in range(3):
        jac = np.zeros((base.size, 4))
        for i in range(4):
            h = 1e-7 * max(1.0, abs(theta[i, j]))
            shifted = theta.copy()
            shifted[i, j] += h
            d = _derived(shifted)
            d[12:15] = Rotation.from_matrix(
                Rotation.from_rotvec(d[12:15]).as_matrix() @ mounting.T
            ).as_rotvec()
            jac[:, i] = (d - np.concatenate([base[:12], np.zeros(3)])) / h
        cov += jac @ (var[j] * inv) @ jac.T
    return np.sqrt(np.diag(cov))


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
