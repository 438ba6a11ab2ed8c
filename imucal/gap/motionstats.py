"""The locations of a recording with an orientation reference and the estimators of its effects.

Its locations are stage ``reference`` x sensor x axis x segment (the recording) x statistic:

* per gyroscope axis, over the reference's intervals (the calibrated gyroscope averaged over
  each interval against the reference's body rate carried into B by the mounting): the
  residual's ``resid_rms``; ``ref_scale``, the slope gyroscope per reference; ``rate2`` and
  ``rate3``, the residual's curvature in the rate (as for a rate table); ``ref_g_slope``, the
  residual per specific force along the axis (gravity from the reference's orientation);
* the orientation integrated from the gyroscope over windows against the reference's
  (:func:`imucal.validation.orientation.window_errors`), ``ori_median_rad`` per window length
  (segment ``{recording}/{T}s``);
* the magnetometer's field direction carried into the reference's world, ``dir_resid_rad``
  (median angle about its mean direction), when the session calibrates the magnetometer.

The estimators (``estimate_*``) of the effects the reference scope estimates (scope ``motion``
of their specs, :mod:`imucal.gap.library`) are here too, next to the statistics they read.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from imucal.columns import AXES
from imucal.gap.disturbance import (
    disturbance_statistics,
)
from imucal.gap.effects import Estimate
from imucal.orientation import (
    interval_means,
    quat_conjugate,
    quat_rotate,
    up_vector,
)
from imucal.validation.orientation import (
    OrientationAlignment,
    field_direction_errors,
    reference_rates,
    window_errors,
)

#: Window lengths of the orientation statistic (s), when the configuration gives none.
WINDOWS_S = (1.0, 10.0)


#: Fewest reference intervals per axis for the rate regressions of a half.
MIN_INTERVALS = 50


@dataclass(frozen=True)
class MotionRecording:
    """One recording with its orientation reference, as the statistics read it.

    Attributes
    ----------
    t_s : ndarray, shape (n,)
        Module times, s.
    gyr : ndarray, shape (n, 3)
        Calibrated gyroscope in B, rad/s.
    mag : ndarray, shape (n, 3), or None
        Calibrated magnetometer in B (normalised), None when the session does not calibrate it.
    t_reference : ndarray, shape (m,)
        Reference times on its own clock, s.
    quat : ndarray, shape (m, 4)
        Reference body -> world, scalar first; NaN rows in its gaps.
    alignment : OrientationAlignment
        Clock and mounting (reference body -> B).
    up : str
        The reference world's up axis (``+z``...).
    acc : ndarray, shape (n, 3), or None
        Calibrated accelerometer in B, m/s^2 (a knock's signature,
        :func:`imucal.gap.disturbance.acc_spikes`); None when the recording has none.
    pos : ndarray, shape (m, 3), or None
        The reference body's position in the reference's world at its samples, m (NaN rows in
        its gaps); None when the reference declares none.
    gyr_full_scale_rad_s : float or None
        The gyroscope's full scale, rad/s (its int16 counts of the twin's quantisation step,
        :attr:`imucal.gap.motiontwin.MotionTwin.gyr_full_scale_rad_s`), which the estimator of
        ``scale_nonlinearity`` reads; None until the twin is built.
    """

    t_s: np.ndarray
    gyr: np.ndarray
    mag: np.ndarray | None
    t_reference: np.ndarray
    quat: np.ndarray
    alignment: OrientationAlignment
    up: str
    acc: np.ndarray | None = None
    pos: np.ndarray | None = None
    gyr_full_scale_rad_s: float | None = None

    def half(self, half: str | None) -> MotionRecording:
        """The first (A) or second (B) half in module time, or the whole (None)."""
        if half is None:
            return self
        mid = 0.5 * (self.t_s[0] + self.t_s[-1])
        keep = self.t_s <= mid if half == "A" else self.t_s > mid
        tau = self.alignment.to_module_time(self.t_reference)
        keep_r = tau <= mid if half == "A" else tau > mid
        return dataclasses.replace(
            self,
            t_s=self.t_s[keep],
            gyr=self.gyr[keep],
            mag=None if self.mag is None else self.mag[keep],
            acc=None if self.acc is None else self.acc[keep],
            t_reference=self.t_reference[keep_r],
            quat=self.quat[keep_r],
            pos=None if self.pos is None else self.pos[keep_r],
        )


def interval_residuals(rec: MotionRecording, gravity_m_s2: float) -> tuple:
    """The calibrated gyroscope against the mounted reference rate over the reference's intervals.

    Returns
    -------
    gyro : ndarray, shape (k, 3)
        Calibrated gyroscope averaged over each interval (B, rad/s).
    rate : ndarray, shape (k, 3)
        The reference's body rate carried into B, rad/s.
    force : ndarray, shape (k, 3)
        Specific force of gravity in B at the interval's start (m/s^2).
    duration : ndarray, shape (k,)
        The interval's length on the reference's clock, s.
    """
    start, end, body = reference_rates(rec.t_reference, rec.quat)
    to_module = rec.alignment.to_module_time
    gyro = interval_means(rec.t_s, rec.gyr, to_module(start), to_module(end))
    mounting = rec.alignment.mounting.matrix
    first = np.searchsorted(rec.t_reference, start)
    up_body = quat_rotate(quat_conjugate(rec.quat[first]), up_vector(rec.up))
    ok = np.all(np.isfinite(gyro), axis=1)
    return (
        gyro[ok],
        body[ok] @ mounting.T,
        gravity_m_s2 * up_body[ok] @ mounting.T,
        (end - start)[ok],
    )


def motion_statistics(
    recordings: Mapping[str, MotionRecording],
    half: str | None = None,
    *,
    windows_s: Sequence[float] = WINDOWS_S,
    gravity_m_s2: float = 9.81,
) -> dict:
    """Every location of the recordings with an orientation reference (module docstring).

    Parameters
    ----------
    recordings : dict of str to MotionRecording
    half : {None, 'A', 'B'}
    windows_s : sequence of float
        Window lengths of ``ori_median_rad``, s.
    gravity_m_s2 : float

    Returns
    -------
    dict
        ``(stage, sensor, axis, segment, statistic)`` -> value.
    """
    out = {}
    for name, whole in recordings.items():
        rec = whole.half(half)
        gyro, rate, force, _ = interval_residuals(rec, gravity_m_s2)
        if len(gyro) >= MIN_INTERVALS:
            res = gyro - rate
            for j, a in enumerate(AXES):
                key = ("reference", "gyr", a, name)
                out[(*key, "resid_rms")] = float(np.sqrt(np.mean(res[:, j] ** 2)))
                centred = gyro[:, j] - gyro[:, j].mean()
                out[(*key, "ref_scale")] = float(
                    np.sum(centred**2) / np.sum(centred * (rate[:, j] - rate[:, j].mean()))
                )
                w = rate[:, j]
                design = np.column_stack([np.ones_like(w), w, w**2, w**3, force[:, j]])
                c, *_ = np.linalg.lstsq(design, res[:, j], rcond=None)
                out[(*key, "rate2")] = float(c[2])
                out[(*key, "rate3")] = float(c[3])
                out[(*key, "ref_g_slope")] = float(c[4])
        errors = window_errors(
            rec.t_s, rec.gyr, rec.t_reference, rec.quat, rec.alignment,
            rec.alignment.mounting.matrix, windows_s,
        )  # fmt: skip
        for key, (_, err) in errors.items():
            if err.size >= 5:
                out[("reference", "gyr", "-", f"{name}/{key}", "ori_median_rad")] = float(
                    np.radians(np.median(err))
                )
        if rec.mag is not None:
            found = field_direction_errors(
                rec.t_s, rec.mag, rec.t_reference, rec.quat, rec.alignment,
                rec.alignment.mounting.matrix, rec.up,
            )  # fmt: skip
            if found["n"] >= MIN_INTERVALS:
                out[("reference", "mag", "-", name, "dir_resid_rad")] = float(
                    np.radians(found["median_deg"])
                )
        out.update(disturbance_statistics(name, rec))
    return out


# --------------------------------------------------------------------------- the effects


def _pooled(session: Mapping[str, MotionRecording], half, gravity_m_s2: float = 9.81):
    parts = [interval_residuals(rec.half(half), gravity_m_s2) for rec in session.values()]
    parts = [p for p in parts if len(p[0]) >= MIN_INTERVALS]
    if not parts:
        return None
    return tuple(np.concatenate([p[k] for p in parts]) for k in range(4))


def estimate_g_sensitivity(session: Mapping[str, MotionRecording], half) -> Estimate | None:
    """Gyroscope output per specific force, the full matrix ``G`` (rad/s per m/s^2, frame B:
    the model term's parameterisation): the residual against the reference, each axis
    regressed on the three components of the specific force with an offset."""
    found = _pooled(session, half)
    if found is None:
        return None
    gyro, rate, force, _ = found
    res = gyro - rate
    design = np.column_stack([np.ones(len(res)), force])
    if np.linalg.matrix_rank(design) < 4:
        return None
    g = np.linalg.lstsq(design, res, rcond=None)[0][1:].T
    return Estimate({"matrix": g.tolist()}, float(np.linalg.norm(g)))


def estimate_scale_nonlinearity(session: Mapping[str, MotionRecording], half) -> Estimate | None:
    """A gyroscope response curved in the rate, common to the axes: the residual against the
    reference regressed on ``FS (k2 x^2 + k3 x^3)`` with ``x = rate / FS`` (an offset and a
    slope per axis: the calibration takes the linear part), ``FS`` the recordings' gyroscope
    full scale (:attr:`MotionRecording.gyr_full_scale_rad_s`).

    Raises
    ------
    ValueError
        If a recording states no full scale.
    """
    scales = {rec.gyr_full_scale_rad_s for rec in session.values()}
    if None in scales or len(scales) != 1:
        raise ValueError(f"the recordings state no single gyroscope full scale: {scales}")
    (full_scale_rad_s,) = scales
    found = _pooled(session, half)
    if found is None:
        return None
    gyro, rate, _, _ = found
    res = gyro - rate
    n = len(res)
    x = rate / full_scale_rad_s
    columns = []
    for j in range(3):
        block = np.zeros((n * 3, 2))
        block[j * n : (j + 1) * n, 0] = 1.0
        block[j * n : (j + 1) * n, 1] = rate[:, j]
        columns.append(block)
    curved = np.column_stack(
        [full_scale_rad_s * (x**2).T.ravel(), full_scale_rad_s * (x**3).T.ravel()]
    )
    design = np.hstack([*columns, curved])
    coef = np.linalg.lstsq(design, res.T.ravel(), rcond=None)[0]
    k2, k3 = float(coef[-2]), float(coef[-1])
    zero = {f"{s}_{k}": 0.0 for s in ("acc", "mag") for k in ("k2", "k3")}
    return Estimate({**zero, "gyr_k2": k2, "gyr_k3": k3}, abs(k2) + abs(k3))


def estimate_reference_jitter(session: Mapping[str, MotionRecording], half) -> Estimate | None:
    """White jitter of the reference's sampling instants: its rate over an interval ``dt``
    errs by ``omega (e_{k+1} - e_k) / dt``, so the squared residual against the gyroscope grows
    as ``2 std^2 omega_j^2 / dt^2`` on axis j above the noise floor; a least-squares fit of
    that line (an intercept per axis, one slope) gives ``std^2``."""
    found = _pooled(session, half)
    if found is None:
        return None
    gyro, rate, _, duration = found
    res = gyro - rate
    n = len(res)
    design = np.zeros((3 * n, 4))
    for j in range(3):
        design[j * n : (j + 1) * n, j] = 1.0
        design[j * n : (j + 1) * n, 3] = 2.0 * rate[:, j] ** 2 / duration**2
    coef = np.linalg.lstsq(design, (res**2).T.ravel(), rcond=None)[0]
    std = float(np.sqrt(max(coef[3], 0.0)))
    return Estimate({"std_s": std}, std)
