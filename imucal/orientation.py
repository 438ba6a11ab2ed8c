"""Orientation series: quaternion algebra, body rates of an orientation reference, gyro integration.

Quaternions are arrays ``(..., 4)``, scalar first ``(w, x, y, z)``, unit norm, rotating vectors
from a body frame to a world frame (``v_world = q v_body q*``), the convention of the ingested
orientation reference (:data:`imucal.columns.QUAT`). Rows of NaN are gaps (tracking lost): no
rate, interval or integral here ever spans one.
"""

from __future__ import annotations

import numpy as np


def quat_multiply(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product ``p q`` of quaternions, shapes (..., 4) broadcast, scalar first."""
    pw, px, py, pz = np.moveaxis(np.asarray(p, dtype=float), -1, 0)
    qw, qx, qy, qz = np.moveaxis(np.asarray(q, dtype=float), -1, 0)
    return np.stack(
        [
            pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw,
        ],
        axis=-1,
    )


def quat_conjugate(q: np.ndarray) -> np.ndarray:
    """Conjugate (the inverse of a unit quaternion), shape (..., 4)."""
    return np.asarray(q, dtype=float) * np.array([1.0, -1.0, -1.0, -1.0])


def quat_from_rotvec(rotvec: np.ndarray) -> np.ndarray:
    """Unit quaternion of rotation vectors ``(..., 3)`` (rad), shape (..., 4)."""
    v = np.asarray(rotvec, dtype=float)
    angle = np.linalg.norm(v, axis=-1, keepdims=True)
    half = 0.5 * angle
    # sin(a/2)/a -> 1/2 for small angles (series to fourth order)
    small = angle < 1e-6
    factor = np.where(small, 0.5 - angle**2 / 48.0, np.sin(half) / np.where(small, 1.0, angle))
    return np.concatenate([np.cos(half), factor * v], axis=-1)


def quat_to_rotvec(q: np.ndarray) -> np.ndarray:
    """Rotation vectors (rad) of unit quaternions ``(..., 4)``, angle in [0, pi], shape (..., 3)."""
    q = np.asarray(q, dtype=float)
    q = np.where(q[..., :1] < 0, -q, q)  # the shorter of the two equivalent rotations
    vec = q[..., 1:]
    s = np.linalg.norm(vec, axis=-1, keepdims=True)
    angle = 2.0 * np.arctan2(s, q[..., :1])
    small = s < 1e-12
    return np.where(small, 2.0 * vec, vec * angle / np.where(small, 1.0, s))


def quat_angle_deg(q: np.ndarray) -> np.ndarray:
    """Rotation angle of unit quaternions ``(..., 4)``, deg in [0, 180], shape (...)."""
    return np.degrees(np.linalg.norm(quat_to_rotvec(q), axis=-1))


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Vectors ``v`` (..., 3) rotated by unit quaternions ``q`` (..., 4): ``q v q*``."""
    v = np.asarray(v, dtype=float)
    pure = np.concatenate([np.zeros(v.shape[:-1] + (1,)), v], axis=-1)
    return quat_multiply(quat_multiply(q, pure), quat_conjugate(q))[..., 1:]


def quat_from_matrix(matrix: np.ndarray) -> np.ndarray:
    """Unit quaternion (scalar first) of a rotation matrix, shape (3, 3) -> (4,)."""
    from scipy.spatial.transform import Rotation

    x, y, z, w = Rotation.from_matrix(np.asarray(matrix, dtype=float)).as_quat()
    return np.array([w, x, y, z])


def body_rates(
    t_s: np.ndarray, quat: np.ndarray, step: int = 1
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean body-frame angular rate over each interval of ``step`` samples of an orientation series.

    Parameters
    ----------
    t_s : array_like, shape (n,)
        Sample times of the orientation, s, strictly increasing.
    quat : array_like, shape (n, 4)
        Unit quaternions, body -> world; NaN rows are gaps.
    step : int
        Interval length in samples (>= 1).

    Returns
    -------
    start_s, end_s : ndarray, shape (m,)
        Interval ends, s; only intervals whose ``step + 1`` samples are all present (none in a
        gap).
    rate : ndarray, shape (m, 3)
        ``rotvec(q(start)* q(end)) / (end - start)``, rad/s: the relative rotation in the body
        frame over the interval divided by its length (the mean body rate up to the coning
        term, of second order in the interval).

    Raises
    ------
    ValueError
        On shapes, a step below 1, or times that do not increase.
    """
    t = np.asarray(t_s, dtype=float)
    q = np.asarray(quat, dtype=float)
    if t.ndim != 1 or q.shape != (t.size, 4):
        raise ValueError(f"expected times (n,) and quaternions (n, 4), got {t.shape}, {q.shape}")
    if step < 1:
        raise ValueError(f"step must be >= 1 sample, got {step}")
    if np.any(np.diff(t) <= 0):
        raise ValueError("the orientation's times must increase strictly")
    present = np.all(np.isfinite(q), axis=1)
    # an interval is usable when all of its step + 1 samples are present
    missing = np.concatenate([[0], np.cumsum(~present)])
    k = np.arange(t.size - step)
    ok = missing[k + step + 1] - missing[k] == 0
    k = k[ok]
    rel = quat_multiply(quat_conjugate(q[k]), q[k + step])
    dt = t[k + step] - t[k]
    return t[k], t[k + step], quat_to_rotvec(rel) / dt[:, None]


def interval_means(
    t_s: np.ndarray, values: np.ndarray, start_s: np.ndarray, end_s: np.ndarray
) -> np.ndarray:
    """Time average of a sampled series over intervals (trapezoid rule, linear between samples).

    Parameters
    ----------
    t_s : array_like, shape (n,)
        Sample times, s, strictly increasing; rows of ``values`` with a NaN are left out.
    values : array_like, shape (n, 3)
    start_s, end_s : array_like, shape (m,)
        Interval ends on the same clock, s.

    Returns
    -------
    ndarray, shape (m, 3)
        NaN for intervals not inside the samples or spanning a step longer than 1.5 times the
        median sample step (a gap of the series).
    """
    t = np.asarray(t_s, dtype=float)
    x = np.asarray(values, dtype=float)
    keep = np.all(np.isfinite(x), axis=1)
    t, x = t[keep], x[keep]
    a = np.asarray(start_s, dtype=float)
    b = np.asarray(end_s, dtype=float)
    out = np.full((a.size, 3), np.nan)
    if t.size < 2:
        return out
    steps = np.diff(t)
    area = np.concatenate([np.zeros((1, 3)), np.cumsum(0.5 * (x[1:] + x[:-1]) * steps[:, None], 0)])

    def integral(tau: np.ndarray) -> np.ndarray:
        i = np.clip(np.searchsorted(t, tau, side="right") - 1, 0, t.size - 2)
        h = (tau - t[i])[:, None]
        slope = (x[i + 1] - x[i]) / steps[i][:, None]
        return area[i] + x[i] * h + 0.5 * slope * h**2

    inside = (a >= t[0]) & (b <= t[-1]) & (b > a)
    big = np.flatnonzero(steps > 1.5 * np.median(steps))
    if big.size:
        gaps = np.concatenate([[0], np.cumsum(np.isin(np.arange(steps.size), big))])
        ia = np.clip(np.searchsorted(t, a, side="right") - 1, 0, steps.size - 1)
        ib = np.clip(np.searchsorted(t, b, side="left") - 1, 0, steps.size - 1)
        inside &= gaps[ib + 1] - gaps[ia] == 0
    out[inside] = (integral(b[inside]) - integral(a[inside])) / (b[inside] - a[inside])[:, None]
    return out


def integrate_rates(t_s: np.ndarray, rates: np.ndarray) -> np.ndarray:
    """Orientation of a body from its body-frame rates, relative to the first sample.

    Parameters
    ----------
    t_s : array_like, shape (n,)
        Sample times, s, strictly increasing.
    rates : array_like, shape (n, 3)
        Body rates, rad/s, finite; each held over the step to the next sample (the mean of the
        two ends, i.e. the trapezoid rule).

    Returns
    -------
    ndarray, shape (n, 4)
        ``q(t_i)`` body(t_i) -> body(t_0), ``q(t_0) = 1``; ``q(t_i)* q(t_j)`` is the rotation
        from ``t_i`` to ``t_j`` in the body frame at ``t_i``.
    """
    t = np.asarray(t_s, dtype=float)
    w = np.asarray(rates, dtype=float)
    steps = quat_from_rotvec(0.5 * (w[1:] + w[:-1]) * np.diff(t)[:, None])
    # inclusive prefix product (Hillis-Steele scan; the product is associative)
    scan = steps.copy()
    shift = 1
    while shift < scan.shape[0]:
        scan[shift:] = quat_multiply(scan[:-shift], scan[shift:])
        shift *= 2
    out = np.empty((t.size, 4))
    out[0] = (1.0, 0.0, 0.0, 0.0)
    out[1:] = scan
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def interpolate_orientation(t_s: np.ndarray, quat: np.ndarray, tau_s: np.ndarray) -> np.ndarray:
    """Orientations at times ``tau_s`` by spherical linear interpolation (slerp) of the neighbours.

    Slerp turns at a constant rate about one axis between two samples, the motion a robot
    makes between two poses; a component-wise interpolation does not (its norm drops between
    samples far apart, and it fails between ``q`` and ``-q``, the same rotation). Neighbours
    of opposite sign are interpolated along the shorter arc.

    Parameters
    ----------
    t_s : ndarray, shape (n,)
        Times of ``quat``, s, increasing, no NaN rows (the neighbours of a gap are not checked).
    quat : ndarray, shape (n, 4)
        Unit quaternions, scalar first.
    tau_s : ndarray, shape (m,)
        Times to interpolate at, s; outside ``t_s`` the end samples are held.

    Returns
    -------
    ndarray, shape (m, 4)
    """
    t = np.asarray(t_s, dtype=float)
    q = np.asarray(quat, dtype=float)
    tau = np.asarray(tau_s, dtype=float)
    i = np.clip(np.searchsorted(t, tau, side="right") - 1, 0, t.size - 2)
    frac = np.clip((tau - t[i]) / (t[i + 1] - t[i]), 0.0, 1.0)[:, None]
    # q_i (q_i* q_i+1)^frac; quat_to_rotvec takes the shorter of the two equivalent rotations
    step = quat_to_rotvec(quat_multiply(quat_conjugate(q[i]), q[i + 1]))
    out = quat_multiply(q[i], quat_from_rotvec(frac * step))
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def up_vector(up: str) -> np.ndarray:
    """Unit vector of a declared up axis (``'+z'``, ``'-y'``, ``'x'``...), shape (3,)."""
    out = np.zeros(3)
    out["xyz".index(up[-1])] = -1.0 if up.startswith("-") else 1.0
    return out
