"""The rows, halves, resting means and clock of a calibrated session, shared by the gap map's
statistics (:mod:`imucal.gap.locations`), the effect estimators (:mod:`imucal.gap.library`)
and the model terms (:mod:`imucal.terms`).

A half (``'A'`` or ``'B'``, :data:`imucal.gap.statistics.HALVES`) is one of the two sets of segments of the
held-out check: alternate positions, runs at alternate rates, the phases x/z against y, the
first and second half of a long recording in time. The resting means are the calibrated means
of the session's resting segments on the session's clock, with their white-noise variances.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation

from imucal import errormodel
from imucal.columns import (
    AXES,
    GYR,
    SENSOR_COLUMNS,
    SENSORS,
    TIME,
    column_values,
    temperature_column,
)
from imucal.constants import SESSION_GAP_S
from imucal.gap.blocks import long_series
from imucal.pipeline.full import SessionFit, calibrated
from imucal.segments.table import row_bounds


def segment_rows(fit: SessionFit, recording: str, kinds) -> pd.DataFrame:
    """The segments of ``recording`` of the given kind(s) in time order (cached per fit: the
    statistics ask for the same rows many times; callers select, they never write)."""
    kinds = (kinds,) if isinstance(kinds, str) else tuple(kinds)
    cache = fit.extra.setdefault("_cache", {}).setdefault("rows", {})
    if (recording, kinds) not in cache:
        seg = fit.segments
        rows = seg[(seg["recording"] == recording) & seg["kind"].isin(kinds)]
        cache[(recording, kinds)] = rows.sort_values("start_s")
    return cache[(recording, kinds)]


def alternate_half(rows: pd.DataFrame, half: str | None) -> pd.DataFrame:
    """Every other row (A: 1st, 3rd, ...; B: 2nd, 4th, ...)."""
    if half is None:
        return rows
    return rows.iloc[0 if half == "A" else 1 :: 2]


def time_half(n: int, half: str | None) -> slice:
    """The rows of ``n`` of a time half: the first (A), the second (B) or all (None)."""
    if half is None:
        return slice(0, n)
    return slice(0, n // 2) if half == "A" else slice(n // 2, n)


def run_half(rows: pd.DataFrame, half: str | None) -> pd.DataFrame:
    """Runs at alternate |rate| levels (A: 100, 300 deg/s; B: 200, 400; rest runs in both)."""
    if half is None:
        return rows
    levels = sorted({abs(r) for r in rows["rate_dps"] if r != 0})
    mine = set(levels[0 if half == "A" else 1 :: 2])
    keep = rows["rate_dps"].abs().isin(mine) | (rows["rate_dps"] == 0)
    return rows[keep]


def phase_half(labels, half: str | None) -> list:
    """The rotation phases of a half: x and z (A), y (B) or all (None)."""
    if half is None:
        return list(labels)
    return [p for p in labels if (p in ("x", "z")) == (half == "A")]


def segment_means(table: np.ndarray, rows: pd.DataFrame) -> np.ndarray:
    out = []
    for a, b in row_bounds(rows):
        x = table[a:b]
        x = x[np.all(np.isfinite(x), axis=1)]
        out.append(x.mean(axis=0) if len(x) else np.full(table.shape[1], np.nan))
    return np.array(out).reshape(-1, table.shape[1])


def mid_times(fit: SessionFit, recording: str, rows: pd.DataFrame) -> np.ndarray:
    return 0.5 * (rows["start_s"].to_numpy(float) + rows["end_s"].to_numpy(float))


def table_residuals(fit: SessionFit, half) -> tuple[pd.DataFrame, np.ndarray, np.ndarray]:
    """Rate-table runs kept by the fit: rows, run-mean residuals (rad/s, (r, 3)), true rates."""
    table = fit.artifacts["gyr_table"]
    rows = segment_rows(fit, "ratetable", "run")
    rows = rows[rows["label"].isin(table["labels"])]
    rows = run_half(rows, half)
    k = np.asarray(table["matrix"], dtype=float)
    b = np.asarray(table["bias"], dtype=float)
    raw = column_values(fit.imu["ratetable"], GYR)
    means = segment_means(raw, rows)
    unit = {a: np.eye(3)[i] for i, a in enumerate(AXES)}
    true = np.array([np.radians(r.rate_dps) * unit[r.axis] for r in rows.itertuples(index=False)])
    return rows, errormodel.apply(k, b, means) - true, true


def magnetometer_lag_fit(fit: SessionFit, phase: str) -> tuple[float, float]:
    """Lag of the calibrated magnetometer behind the gyroscope during one phase, and its
    standard deviation (s; NaN without the phase).

    The field, fixed in the world, turns in B at minus the body rate about the phase axis, so
    ``angle_m(t) + angle_g(t) = c + rate(t) * lag`` with ``angle_m`` the unwrapped angle of
    the field's component across the axis and ``angle_g`` the integrated rate; the slope on
    the rate is the lag (positive: the magnetometer reports late). The standard deviation is
    that of least squares with the residual variance of the phase's field samples.
    """
    rows = segment_rows(fit, "rotation3d", "phase")
    r = rows[rows["label"] == phase]
    if r.empty:
        return float("nan"), float("nan")
    r = r.iloc[0]
    sl = slice(int(r.start_index), int(r.end_index))
    t = fit.imu["rotation3d"][TIME].to_numpy(dtype=float)[sl]
    mag = calibrated(fit, "rotation3d", "mag")[sl]
    gyr = calibrated(fit, "rotation3d", "gyr")[sl]
    j = AXES.index(phase)
    u, v = [(j + 1) % 3, (j + 2) % 3]
    w = gyr[:, j]
    theta = np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(t))])
    fresh = np.all(np.isfinite(mag), axis=1)
    ang = np.unwrap(np.arctan2(mag[fresh, v], mag[fresh, u]))
    y = ang + theta[fresh]
    x = w[fresh]
    design = np.column_stack([np.ones_like(x), x])
    c, *_ = np.linalg.lstsq(design, y, rcond=None)
    dof = max(len(y) - 2, 1)
    sigma2 = float(np.sum((y - design @ c) ** 2) / dof)
    return float(c[1]), float(np.sqrt(np.linalg.pinv(design.T @ design)[1, 1] * sigma2))


def integrate_orientation(t_s: np.ndarray, omega: np.ndarray, q0: np.ndarray) -> np.ndarray:
    """Orientation B -> world by integrating body rates (trapezoidal increments).

    Parameters
    ----------
    t_s : ndarray, shape (n,)
        Sample times (s).
    omega : ndarray, shape (n, 3)
        Calibrated angular rate in B (rad/s).
    q0 : ndarray, shape (4,)
        Initial orientation, scalar-last quaternion.

    Returns
    -------
    ndarray, shape (n, 4)
        Scalar-last quaternions.
    """
    rv = 0.5 * (omega[1:] + omega[:-1]) * np.diff(t_s)[:, None]
    dq = Rotation.from_rotvec(np.nan_to_num(rv)).as_quat()
    q = np.empty((len(t_s), 4))
    x, y, z, w = (float(v) for v in q0)
    q[0] = x, y, z, w
    for k, (bx, by, bz, bw) in enumerate(dq.tolist(), start=1):
        x, y, z, w = (
            w * bx + x * bw + y * bz - z * by,
            w * by - x * bz + y * bw + z * bx,
            w * bz + x * by - y * bx + z * bw,
            w * bw - x * bx - y * by - z * bz,
        )
        q[k] = x, y, z, w
    return q


def session_clock(fit: SessionFit) -> dict:
    """Start of each recording (s) on the session clock of the simulator and the twin: the
    recordings one after another in the protocol's order (rotation3d, cube, ratetable,
    static), ``SESSION_GAP_S`` apart. Real recordings carry no common clock; this is the
    assumption the diagnosis and the temperature term make about their order."""
    starts, t = {}, 0.0
    for name in ("rotation3d", "cube", "ratetable", "static"):
        if name in fit.imu:
            starts[name] = t
            tt = fit.imu[name][TIME].to_numpy(dtype=float)
            t += tt[-1] - tt[0] + SESSION_GAP_S
    return starts


def resting_rows(fit: SessionFit, half) -> list[tuple[str, pd.DataFrame]]:
    """The session's resting segments per recording: rotation3d rests, cube positions, the rate
    table's runs at 0 deg/s and the static recording cut in 8 blocks (every other one for a
    half); recordings in the protocol's order, segments in time order within each. Holds of
    a recording held by hand (``options.held_by_hand``) are not rest and are left out."""
    out = []
    held = fit.extra["options"].held_by_hand
    for rec, kind in (("rotation3d", "static"), ("cube", "position"), ("ratetable", "run"),
                      ("static", "static")):  # fmt: skip
        if rec not in fit.imu or rec in held:
            continue
        rows = segment_rows(fit, rec, kind)
        if rec == "ratetable":
            rows = rows[rows["rate_dps"] == 0]
        rows = alternate_half(rows, half)
        if rec == "static":
            t = _resting_source(fit, rec)[0][TIME].to_numpy(dtype=float)
            edges = np.linspace(0, len(t), 9).astype(int)
            rows = pd.DataFrame({"start_index": edges[:-1], "end_index": edges[1:],
                                 "start_s": t[edges[:-1]], "end_s": t[edges[1:] - 1]})  # fmt: skip
            rows = rows.iloc[0 if half in (None, "A") else 1 :: 1 if half is None else 2]
        out.append((rec, rows))
    return out


@dataclass(frozen=True)
class RestingMeans:
    """Means of the session's resting segments (:func:`resting_rows`), one row per segment.

    Attributes
    ----------
    recording : list of str
        Recording of each segment, length r.
    mid_s : ndarray, shape (r,)
        Middle of the segment (s) from its recording's first sample.
    gyr, acc : ndarray, shape (r, 3)
        Calibrated means (rad/s, m/s^2, frame B).
    gyr_var : ndarray, shape (r, 3)
        White-noise variance of the gyro means ((rad/s)^2), from first differences, floored at
        the quantisation's.
    acc_var : ndarray, shape (r,)
        White-noise variance of one accelerometer axis's mean ((m/s^2)^2), averaged over axes.
    north, east, up : ndarray, shape (r, 3)
        The world's magnetic north, east and up in frame B (unit vectors; NaN without
        magnetometer samples in the segment).
    temp : ndarray, shape (r,)
        Mean temperature (deg C); NaN where the recording has no channel.
    """

    recording: list
    mid_s: np.ndarray
    gyr: np.ndarray
    gyr_var: np.ndarray
    acc: np.ndarray
    acc_var: np.ndarray
    north: np.ndarray
    east: np.ndarray
    up: np.ndarray
    temp: np.ndarray

    def __len__(self) -> int:
        return len(self.recording)


def white_variance(x: np.ndarray, floor: float) -> np.ndarray:
    """White-noise variance of the mean of ``x`` (n, k) per column, at least ``floor / n``."""
    return np.maximum(np.var(np.diff(x, axis=0), axis=0) / 2, floor) / len(x)


def _resting_source(fit: SessionFit, recording: str) -> tuple[pd.DataFrame, float, tuple, dict]:
    """The rows a recording's resting means are taken from: the table (block means for a long
    static recording), its first sample's time, the calibrated gyro, acc and mag (n, 3) and
    the samples per row of each sensor."""
    if recording != "static":
        table = fit.imu[recording]
        cal = tuple(calibrated(fit, recording, s) for s in ("gyr", "acc", "mag"))
        return table, float(table[TIME].iloc[0]), cal, dict.fromkeys(SENSORS, 1.0)
    blocks = fit.extra.get("static_blocks")
    table, samples, start = long_series(fit.imu, blocks)
    if blocks is None:
        cal = tuple(calibrated(fit, recording, s) for s in ("gyr", "acc", "mag"))
        return table, start, cal, samples
    cache = fit.extra.setdefault("calibrated", {})
    for s in SENSORS:
        if ("static blocks", s) not in cache:
            c = fit.calibration.sensor(s)
            # the calibration is affine: the calibrated block mean is the block mean calibrated
            out = c.apply(column_values(table, SENSOR_COLUMNS[s]), unit=c.unit)
            out.flags.writeable = False
            cache[("static blocks", s)] = out
    cal = tuple(cache[("static blocks", s)] for s in ("gyr", "acc", "mag"))
    return table, start, cal, samples


def resting_means(fit: SessionFit, half) -> RestingMeans:
    """The calibrated means of every resting segment of the session (segments with fewer than 3
    complete gyro and accelerometer samples are skipped). Cached per fit and half, read-only."""
    cache = fit.extra.setdefault("_cache", {}).setdefault("resting", {})
    if half not in cache:
        cache[half] = _resting_means(fit, half)
    return cache[half]


def _resting_means(fit: SessionFit, half) -> RestingMeans:
    sens = fit.extra["options"].sensitivity
    rows_out = {k: [] for k in RestingMeans.__dataclass_fields__}
    for rec, rows in resting_rows(fit, half):
        table, t0, (w, a, m), samples = _resting_source(fit, rec)
        col = temperature_column(table)
        temp = table[col].to_numpy(dtype=float) if col else None
        mids = 0.5 * (rows["start_s"].to_numpy(float) + rows["end_s"].to_numpy(float)) - t0
        for (start, end), mid in zip(row_bounds(rows), mids, strict=True):
            sl = slice(start, end)
            ws = w[sl][np.all(np.isfinite(w[sl]), axis=1)]
            as_ = a[sl][np.all(np.isfinite(a[sl]), axis=1)]
            if len(ws) < 3 or len(as_) < 3:
                continue
            north = east = up = np.full(3, np.nan)
            ms = m[sl][np.all(np.isfinite(m[sl]), axis=1)]
            up_ = as_.mean(axis=0) / np.linalg.norm(as_.mean(axis=0))
            if len(ms):
                e = np.cross(ms.mean(axis=0), up_)  # north x up = east
                if np.linalg.norm(e) > 0:
                    east = e / np.linalg.norm(e)
                    up = up_
                    north = np.cross(up, east)
            rows_out["recording"].append(rec)
            rows_out["mid_s"].append(mid)
            rows_out["gyr"].append(ws.mean(axis=0))
            q_gyr, q_acc = (float(sens[s]) ** 2 / 12 / samples[s] for s in ("gyr", "acc"))
            rows_out["gyr_var"].append(white_variance(ws, q_gyr))
            rows_out["acc"].append(as_.mean(axis=0))
            rows_out["acc_var"].append(float(np.mean(white_variance(as_, q_acc))))
            rows_out["north"].append(north)
            rows_out["east"].append(east)
            rows_out["up"].append(up)
            seg_temp = temp[sl] if temp is not None else np.array([np.nan])
            rows_out["temp"].append(
                float(np.nanmean(seg_temp)) if np.any(np.isfinite(seg_temp)) else np.nan
            )
    vectors = {k: np.array(rows_out[k], dtype=float).reshape(-1, 3)
               for k in ("gyr", "gyr_var", "acc", "north", "east", "up")}  # fmt: skip
    scalars = {k: np.array(rows_out[k], dtype=float) for k in ("mid_s", "acc_var", "temp")}
    for v in (*vectors.values(), *scalars.values()):
        v.flags.writeable = False
    return RestingMeans(recording=rows_out["recording"], **vectors, **scalars)
