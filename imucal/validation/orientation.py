"""An orientation reference (motion capture, robot): time alignment, mounting and agreement.

The reference gives the orientation of its body (a marker set, a robot flange) in its world
frame; the module's gyroscope measures the body rate in frame B. Their relation has three
unknowns, estimated here from the data:

* the clock: the reference's body rate, from the relative rotation between consecutive
  orientations (:func:`imucal.orientation.body_rates`), has the same ``|omega|^2`` as the
  gyroscope's whatever the mounting, so the offset and drift come from
  :func:`imucal.validation.timing.estimate_time_alignment` (convention
  :data:`imucal.validation.timing.TIME_CONVENTION`);
* the mounting ``M`` (reference body -> B, ``omega_B = M omega_body``): the rotation axes of the
  relative rotations over the same intervals seen by both (hand-eye calibration in its rate
  form, ``A X = X B`` with small rotations), solved as a Wahba problem
  (:func:`imucal.validation.mounting.estimate_mounting`);
* then the agreement: per-axis rates, the orientation change integrated from the gyroscope over
  windows against the reference's, and the gravity direction at rests.

Gaps of the reference (tracking lost) are never bridged: a rate needs both ends of its interval,
a window both of its ends, and the time fit leaves out module samples inside a gap.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from imucal.orientation import (
    body_rates,
    integrate_rates,
    interpolate_orientation,
    interval_means,
    quat_angle_deg,
    quat_conjugate,
    quat_from_matrix,
    quat_multiply,
    quat_rotate,
    up_vector,
)
from imucal.validation.mounting import Mounting, estimate_mounting
from imucal.validation.timing import TimeAlignment, estimate_time_alignment

#: Below this correlation of ``|omega|^2`` the reference's rate does not match the gyroscope's:
#: a wrong column order or scalar position scrambles the rates, a wrong rate_hz stretches them.
MIN_RATE_CORRELATION = 0.5
#: Below this share of the gyroscope's rate variance explained by the mounted reference rate,
#: the reference's body rates are not the gyroscope's (e.g. a world-to-body rotation declared as
#: body-to-world gives world-frame rates).
MIN_EXPLAINED = 0.5


@dataclass(frozen=True)
class OrientationAlignment:
    """Clock and mounting of an orientation reference against the module's gyroscope.

    Attributes
    ----------
    time : TimeAlignment
        ``t_ref = offset_s + (1 + drift_ppm 1e-6) t_module``.
    mounting : Mounting
        ``M`` with ``omega_B = M omega_body`` (reference body -> frame of the gyroscope used).
    explained : float
        Share of the gyroscope's rate variance explained by ``M omega_body`` (1 - residual /
        total), over the intervals used.
    n_intervals : int
        Reference intervals used for the mounting.
    reference_period_s : float
        Median sample step of the reference, s (the unit of the offset's acceptance).
    """

    time: TimeAlignment
    mounting: Mounting
    explained: float
    n_intervals: int
    reference_period_s: float

    def to_module_time(self, t_reference: np.ndarray) -> np.ndarray:
        """Module-clock times of reference-clock times (shape (n,), s)."""
        t = np.asarray(t_reference, dtype=float)
        return (t - self.time.offset_s) / (1.0 + self.time.drift_ppm * 1e-6)

    def to_dict(self) -> dict:
        return {
            "time": self.time.to_dict(),
            "mounting": self.mounting.to_dict(),
            "explained": self.explained,
            "n_intervals": self.n_intervals,
            "reference_period_s": self.reference_period_s,
        }


def _check(t: np.ndarray, x: np.ndarray, width: int, name: str) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(t, dtype=float)
    x = np.asarray(x, dtype=float)
    if t.ndim != 1 or x.shape != (t.size, width):
        raise ValueError(
            f"{name}: expected times (n,) and values (n, {width}), got {t.shape}, {x.shape}"
        )
    return t, x


def reference_rates(
    t_reference: np.ndarray, quat_reference: np.ndarray, step: int = 1
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Body rates of the reference per interval (:func:`imucal.orientation.body_rates`)."""
    t, q = _check(t_reference, quat_reference, 4, "reference")
    return body_rates(t, q, step)


def align_orientation_reference(
    t_module: np.ndarray,
    gyr_module: np.ndarray,
    t_reference: np.ndarray,
    quat_reference: np.ndarray,
    *,
    where: str = "reference",
) -> OrientationAlignment:
    """Time offset, drift and mounting of an orientation reference from the gyroscope.

    Parameters
    ----------
    t_module : array_like, shape (n,)
        Module sample times, s, strictly increasing.
    gyr_module : array_like, shape (n, 3)
        Gyroscope, rad/s, bias removed (calibrated is best); NaN rows are left out.
    t_reference : array_like, shape (m,)
        Reference times on its own clock, s, strictly increasing.
    quat_reference : array_like, shape (m, 4)
        Unit quaternions body -> world, scalar first; NaN rows are gaps.
    where : str
        The declaration's key path (``<dataset.yaml>: recordings.<name>.reference``), the prefix
        of the errors about it.

    Returns
    -------
    OrientationAlignment

    Raises
    ------
    ValueError
        Named after ``where``: no overlap in time, a rate that does not match the gyroscope's
        (wrong columns, scalar position or rate), or body rates that no fixed rotation maps onto
        the gyroscope's (wrong ``rotates``).
    """
    t_m, w_m = _check(t_module, gyr_module, 3, "module")
    start, end, rate = reference_rates(t_reference, quat_reference)
    if rate.shape[0] < 10:
        raise ValueError(
            f"{where}: {rate.shape[0]} intervals of consecutive orientations; expected at least "
            "10 (the reference is mostly gaps)"
        )
    period = float(np.median(np.diff(np.asarray(t_reference, dtype=float))))
    try:
        time = estimate_time_alignment(
            t_m, w_m, 0.5 * (start + end), rate, reference_max_gap_s=1.5 * period
        )
    except ValueError as err:
        raise ValueError(
            f"{where}: the reference's angular rate could not be aligned in time with the "
            f"gyroscope's ({err}); expected the reference to overlap the recording in time "
            "(check its t_s or rate_hz)"
        ) from None
    if not time.correlation >= MIN_RATE_CORRELATION:
        raise ValueError(
            f"{where}: the reference's |omega|^2 correlates with the gyroscope's by "
            f"{time.correlation:.2f} at the best offset {time.offset_s:.3f} s; expected at least "
            f"{MIN_RATE_CORRELATION}: check .columns and .scalar (the component order), .rate_hz "
            "or the t_s column, and that the reference was recorded with this recording"
        )
    return mount_orientation_reference(t_m, w_m, t_reference, quat_reference, time, where=where)


def mount_orientation_reference(
    t_module: np.ndarray,
    gyr_module: np.ndarray,
    t_reference: np.ndarray,
    quat_reference: np.ndarray,
    time: TimeAlignment,
    *,
    where: str = "reference",
) -> OrientationAlignment:
    """The mounting of an orientation reference for a given clock relation (hand-eye, Wahba).

    Parameters and errors as :func:`align_orientation_reference`, with the clock ``time``
    given (e.g. found once with the bias-corrected gyroscope and reused for the calibrated
    one, whose frame differs but whose ``|omega|`` is the same up to the calibration).
    """
    t_m, w_m = _check(t_module, gyr_module, 3, "module")
    start, end, rate = reference_rates(t_reference, quat_reference)
    period = float(np.median(np.diff(np.asarray(t_reference, dtype=float))))
    alignment = OrientationAlignment(time, _identity_mounting(), 0.0, 0, period)
    a, b = alignment.to_module_time(start), alignment.to_module_time(end)
    means = interval_means(t_m, w_m, a, b)
    mounting = estimate_mounting({"gyr": means}, {"gyr": rate})
    ok = np.all(np.isfinite(means), axis=1)
    residual = means[ok] - rate[ok] @ mounting.matrix.T
    spread = means[ok] - means[ok].mean(axis=0)
    explained = 1.0 - float(np.sum(residual**2) / np.sum(spread**2))
    if explained < MIN_EXPLAINED:
        raise ValueError(
            f"{where}: the mounted reference body rates explain {explained:.0%} of the "
            f"gyroscope's rate variance; expected at least {MIN_EXPLAINED:.0%}: check "
            f"{where.rsplit(': ', 1)[-1]}.rotates (body_to_world declared as world_to_body, or "
            "the reverse, gives world-frame rates) and .scalar (the position of w)"
        )
    return OrientationAlignment(time, mounting, explained, int(np.count_nonzero(ok)), period)


def aligned_intervals(
    t_module: np.ndarray,
    gyr_module: np.ndarray,
    t_reference: np.ndarray,
    quat_reference: np.ndarray,
    alignment: OrientationAlignment,
) -> tuple[np.ndarray, np.ndarray]:
    """The gyroscope averaged over each reference interval, beside the reference's body rate.

    Returns
    -------
    readings : ndarray, shape (k, 3)
        ``gyr_module`` (any unit, as given) averaged over the interval on the module clock;
        NaN where the interval is not inside the module's samples.
    rates : ndarray, shape (k, 3)
        The reference's body rate over the interval, rad/s.
    """
    start, end, rate = reference_rates(t_reference, quat_reference)
    a, b = alignment.to_module_time(start), alignment.to_module_time(end)
    return interval_means(t_module, gyr_module, a, b), rate


def _identity_mounting() -> Mounting:
    return Mounting(np.eye(3), np.zeros(3), 0.0, 0.0, {}, {})


# --------------------------------------------------------------------------- agreement


def rate_agreement(
    t_module: np.ndarray,
    gyr_b: np.ndarray,
    t_reference: np.ndarray,
    quat_reference: np.ndarray,
    alignment: OrientationAlignment,
    mounting: np.ndarray,
) -> dict:
    """Per-axis agreement of the gyroscope with the mounted reference rate over its intervals.

    Parameters
    ----------
    t_module, gyr_b : shapes (n,), (n, 3)
        Module times (s) and gyroscope in frame B (rad/s).
    t_reference, quat_reference : shapes (m,), (m, 4)
    alignment : OrientationAlignment
        For the clock.
    mounting : array_like, shape (3, 3)
        ``M``: reference body -> B.

    Returns
    -------
    dict
        Per axis ``x``, ``y``, ``z``: ``rms_rad_s`` (of gyro - reference), ``mean_rad_s``,
        ``slope`` (gyro per reference: the inverse of the least-squares slope of the reference
        on the gyroscope, unbiased by the reference's noise), ``correlation``; and
        ``n_intervals``.
    """
    start, end, rate = reference_rates(t_reference, quat_reference)
    means = interval_means(
        t_module, gyr_b, alignment.to_module_time(start), alignment.to_module_time(end)
    )
    ok = np.all(np.isfinite(means), axis=1)
    ref = rate[ok] @ np.asarray(mounting, dtype=float).T
    gyro = means[ok]
    out: dict = {"n_intervals": int(np.count_nonzero(ok))}
    for k, axis in enumerate("xyz"):
        diff = gyro[:, k] - ref[:, k]
        # gyro per reference from the regression of the reference on the gyroscope: the
        # finite-difference reference is the noisy one, which would bias the direct slope down
        centred = gyro[:, k] - gyro[:, k].mean()
        slope = float(np.sum(centred**2) / np.sum(centred * (ref[:, k] - ref[:, k].mean())))
        out[axis] = {
            "rms_rad_s": float(np.sqrt(np.mean(diff**2))),
            "mean_rad_s": float(np.mean(diff)),
            "slope": slope,
            "correlation": float(np.corrcoef(ref[:, k], gyro[:, k])[0, 1]),
        }
    return out


def window_errors(
    t_module: np.ndarray,
    gyr_b: np.ndarray,
    t_reference: np.ndarray,
    quat_reference: np.ndarray,
    alignment: OrientationAlignment,
    mounting: np.ndarray,
    windows_s: Sequence[float],
    stride_s: float = 1.0,
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Orientation change integrated from the gyroscope over windows against the reference's.

    For each window ``[s, s + T]`` both ends are reference samples present (not in a gap; what
    happens between them does not matter, nothing is interpolated across a gap), starting every
    ``stride_s``. The gyroscope (frame B) is integrated over the same module-clock interval; the
    error is the angle of ``Q_gyro^-1 M Q_ref M^-1`` with ``Q_ref`` the reference's relative
    rotation in its body frame. The windows depend on the clock and the reference's gaps only,
    so two gyroscopes compared with the same clock get the same windows (a paired comparison).

    Parameters
    ----------
    t_module, gyr_b, t_reference, quat_reference, alignment, mounting
        As in :func:`rate_agreement`.
    windows_s : sequence of float
        Window lengths, s (the workflow's ``reference.windows_s``).
    stride_s : float
        Step between window starts, s.

    Returns
    -------
    dict
        Per window (key ``f"{T:g}s"``): ``(starts, errors)``, the reference time of each
        window's start (s) and its orientation error (deg), shapes (k,).
    """
    t_m, w = _check(t_module, gyr_b, 3, "module")
    keep = np.all(np.isfinite(w), axis=1)
    t_m, w = t_m[keep], w[keep]
    t_r, q_r = _check(t_reference, quat_reference, 4, "reference")
    present = np.all(np.isfinite(q_r), axis=1)
    t_valid, q_valid = t_r[present], q_r[present]
    integrated = integrate_rates(t_m, w)
    q_mount = quat_from_matrix(mounting)
    period = alignment.reference_period_s
    out = {}
    for window in windows_s:
        tau_start = np.arange(t_r[0], t_r[-1] - window, stride_s)
        i = np.clip(np.searchsorted(t_valid, tau_start), 0, t_valid.size - 1)
        j = np.clip(np.searchsorted(t_valid, t_valid[i] + window), 0, t_valid.size - 1)
        fits = (np.abs(t_valid[i] - tau_start) <= 2 * period) & (
            np.abs(t_valid[j] - t_valid[i] - window) <= 2 * period
        )
        a, b = alignment.to_module_time(t_valid[i]), alignment.to_module_time(t_valid[j])
        fits &= (a >= t_m[0]) & (b <= t_m[-1])
        errors = np.array([])
        if np.any(fits):
            i, j, a, b = i[fits], j[fits], a[fits], b[fits]
            rel_g = quat_multiply(
                quat_conjugate(interpolate_orientation(t_m, integrated, a)),
                interpolate_orientation(t_m, integrated, b),
            )
            rel_r = quat_multiply(quat_conjugate(q_valid[i]), q_valid[j])
            rel_r_b = quat_multiply(quat_multiply(q_mount, rel_r), quat_conjugate(q_mount))
            errors = quat_angle_deg(quat_multiply(quat_conjugate(rel_g), rel_r_b))
        out[f"{window:g}s"] = (tau_start[fits], errors)
    return out


def orientation_errors(
    t_module: np.ndarray,
    gyr_b: np.ndarray,
    t_reference: np.ndarray,
    quat_reference: np.ndarray,
    alignment: OrientationAlignment,
    mounting: np.ndarray,
    windows_s: Sequence[float],
    stride_s: float = 1.0,
) -> dict:
    """:func:`window_errors` summarised per window (:func:`summarise_windows`)."""
    found = window_errors(
        t_module, gyr_b, t_reference, quat_reference, alignment, mounting, windows_s, stride_s
    )
    return summarise_windows(found, windows_s)


def summarise_windows(
    found: Mapping[str, tuple[np.ndarray, np.ndarray]], windows_s: Sequence[float]
) -> dict:
    """Summary of :func:`window_errors`' result per window.

    Returns
    -------
    dict
        Per window (key ``f"{T:g}s"``): ``n``, ``median_deg``, ``rms_deg``, ``p95_deg``,
        ``max_deg`` (None when no window fits), ``window_s``.
    """
    return {
        key: _stats(errors) | {"window_s": float(window)}
        for (key, (_, errors)), window in zip(found.items(), windows_s, strict=True)
    }


def compare_window_errors(
    candidate: tuple[np.ndarray, np.ndarray],
    baseline: tuple[np.ndarray, np.ndarray],
    window_s: float,
    alpha: float = 0.05,
) -> dict:
    """Does one gyroscope's orientation error differ from another's over the same windows?

    Windows that overlap share their errors, so only windows at least ``window_s`` apart
    enter: a greedy choice of non-overlapping windows present in both. Their paired
    differences go through the Wilcoxon signed-rank test (two-sided; no assumption on the
    errors' distribution, which is far from normal).

    Parameters
    ----------
    candidate, baseline : (starts, errors)
        As :func:`window_errors` returns them for one window length.
    window_s : float
        The window length, s.
    alpha : float
        Level of the test.

    Returns
    -------
    dict
        ``n_windows`` (independent pairs), ``median_difference_deg`` (candidate - baseline),
        ``p_value`` (None with fewer than 6 pairs, too few for the test at 5 %), ``verdict``:
        ``better``, ``worse``, ``no significant difference`` or ``too few windows``.
    """
    from scipy.stats import wilcoxon

    start_c, err_c = candidate
    start_b, err_b = baseline
    common, ic, ib = np.intersect1d(start_c, start_b, return_indices=True)
    chosen, last = [], -np.inf
    for k, start in enumerate(common):
        if start >= last + window_s:
            chosen.append(k)
            last = start
    diff = err_c[ic[chosen]] - err_b[ib[chosen]]
    out = {"n_windows": int(diff.size), "median_difference_deg": None, "p_value": None}
    if diff.size < 6:
        return out | {"verdict": "too few windows"}
    p = float(wilcoxon(diff).pvalue)
    median = float(np.median(diff))
    verdict = "no significant difference"
    if p < alpha:
        verdict = "better" if median < 0 else "worse"
    return out | {"median_difference_deg": median, "p_value": p, "verdict": verdict}


def _stats(errors: np.ndarray) -> dict:
    if errors.size == 0:
        return {"n": 0, "median_deg": None, "rms_deg": None, "p95_deg": None, "max_deg": None}
    return {
        "n": int(errors.size),
        "median_deg": float(np.median(errors)),
        "rms_deg": float(np.sqrt(np.mean(errors**2))),
        "p95_deg": float(np.percentile(errors, 95)),
        "max_deg": float(np.max(errors)),
    }


def gravity_errors(
    t_module: np.ndarray,
    acc_b: np.ndarray,
    rests_s: Sequence[tuple[float, float]],
    t_reference: np.ndarray,
    quat_reference: np.ndarray,
    alignment: OrientationAlignment,
    mounting: np.ndarray,
    up: str,
) -> dict:
    """Gravity direction at rests: the accelerometer's against the reference's.

    Parameters
    ----------
    t_module, acc_b : shapes (n,), (n, 3)
        Module times (s) and accelerometer in frame B (m/s^2).
    rests_s : sequence of (start, end)
        Rests on the module clock, s.
    t_reference, quat_reference, alignment, mounting
        As in :func:`rate_agreement`.
    up : str
        The reference world's axis that points up (``+z`` for ENU).

    Returns
    -------
    dict
        ``angles_deg`` per rest (None where the reference has no sample in it), ``median_deg``,
        ``max_deg``, ``n``. The accelerometer reads +g along up at rest.
    """
    t_m, acc = _check(t_module, acc_b, 3, "module")
    t_r, q_r = _check(t_reference, quat_reference, 4, "reference")
    up_world = up_vector(up)
    t_r_m = alignment.to_module_time(t_r)
    present = np.all(np.isfinite(q_r), axis=1)
    angles: list[float | None] = []
    for lo, hi in rests_s:
        sel_r = present & (t_r_m >= lo) & (t_r_m <= hi)
        sel_m = (t_m >= lo) & (t_m <= hi) & np.all(np.isfinite(acc), axis=1)
        if not sel_r.any() or not sel_m.any():
            angles.append(None)
            continue
        up_body = quat_rotate(quat_conjugate(q_r[sel_r]), up_world).mean(axis=0)
        ref = np.asarray(mounting, dtype=float) @ up_body
        meas = acc[sel_m].mean(axis=0)
        cos = ref @ meas / (np.linalg.norm(ref) * np.linalg.norm(meas))
        angles.append(float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))))
    found = np.array([a for a in angles if a is not None])
    return {
        "angles_deg": angles,
        "n": int(found.size),
        "median_deg": float(np.median(found)) if found.size else None,
        "max_deg": float(np.max(found)) if found.size else None,
    }


def field_direction_errors(
    t_module: np.ndarray,
    mag_b: np.ndarray,
    t_reference: np.ndarray,
    quat_reference: np.ndarray,
    alignment: OrientationAlignment,
    mounting: np.ndarray,
    up: str,
) -> dict:
    """The magnetometer's field direction carried into the reference's world: is it constant?

    At every present reference sample the magnetometer (interpolated to it on the module
    clock, never across a gap of the reference since only present samples enter) is rotated
    into the world, ``m_w = R_ref M^T m_B``. In an undisturbed field ``m_w`` is one constant
    direction; its scatter about the mean direction measures what the magnetometer's
    calibration (hard and soft iron, its alignment to the gyroscope's frame B) leaves, together
    with field disturbances of the room.

    Parameters
    ----------
    t_module, mag_b : shapes (n,), (n, 3)
        Module times (s) and magnetometer in frame B (any unit: only directions count).
    t_reference, quat_reference, alignment, mounting
        As in :func:`rate_agreement`.
    up : str
        The reference world's up axis (``+z`` for ENU), for the dip angle.

    Returns
    -------
    dict
        ``n`` (reference samples used), ``median_deg``, ``p95_deg``, ``max_deg`` of the angle
        between ``m_w`` and its mean direction, and ``dip_deg`` of the mean direction (positive
        below the horizon); None values when no sample overlaps.
    """
    t_m, m = _check(t_module, mag_b, 3, "module")
    keep = np.all(np.isfinite(m), axis=1)
    t_m, m = t_m[keep], m[keep]
    t_r, q_r = _check(t_reference, quat_reference, 4, "reference")
    tau = alignment.to_module_time(t_r)
    use = np.all(np.isfinite(q_r), axis=1) & (tau >= t_m[0]) & (tau <= t_m[-1])
    if not use.any():
        return {"n": 0, "median_deg": None, "p95_deg": None, "max_deg": None, "dip_deg": None}
    m_at = np.column_stack([np.interp(tau[use], t_m, m[:, k]) for k in range(3)])
    body = m_at @ np.asarray(mounting, dtype=float)  # rows M^T m_B
    world = quat_rotate(q_r[use], body)
    world /= np.linalg.norm(world, axis=1, keepdims=True)
    mean = world.mean(axis=0)
    mean /= np.linalg.norm(mean)
    angles = np.degrees(np.arccos(np.clip(world @ mean, -1.0, 1.0)))
    up_world = up_vector(up)
    return {
        "n": int(angles.size),
        "median_deg": float(np.median(angles)),
        "p95_deg": float(np.percentile(angles, 95)),
        "max_deg": float(np.max(angles)),
        "dip_deg": float(np.degrees(np.arcsin(np.clip(-mean @ up_world, -1.0, 1.0)))),
    }
