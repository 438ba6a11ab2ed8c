"""Temperature terms held out across static poses: each pose predicted from the others.

A recording of a motionless IMU left in a few static poses while its temperature sweeps (a
thermal chamber, a tag in a fridge) shows each sensor's drift with temperature, but every pose
adds its own constant: gravity along another axis, the g-sensitivity of the gyroscope, the
accelerometer's scale along that axis. So a pose's drift is predictable from the others only
up to its constant, and that is the test here: hold each pose out in turn, fit on the others,
predict the held-out pose's signal against its temperature, remove the constant, and compare
the residual RMS per pose, sensor and axis for

* ``none``: no temperature term (the held-out signal about its own mean);
* ``term``: this project's temperature term, a polynomial ``sum_k c_k dT^k`` per axis with one
  constant per fit pose as a nuisance (the constants absorb the orientation), its order
  ``0 .. max_order`` chosen per axis on the held-out poses (:func:`choose_order`, the
  one-standard-error rule of :func:`imucal.terms.temperature.select_model`), so an axis where
  no polynomial predicts the held-out poses better than none gets no term;
* ``regression``: the approach of scikit-diveMove's ``IMUcalibrate`` (Luque): per axis, a
  linear regression of the static signal on temperature with one intercept, pooled over the
  fit poses' samples.

The held-out pose is compared on its samples within the fit poses' temperature span widened by
``margin_c`` (where the term calibrates; beyond it :class:`imucal.modelterms.TemperaturePolynomial`
refuses), all three on the same samples. The term is fitted to block means of ``block_s`` (the
drift; the white noise averages out), the regression to the samples as ``IMUcalibrate`` does;
the comparison is on every sample and on the block means.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from imucal.columns import (
    AXES,
    POSE_KINDS,
    SENSOR_COLUMNS,
    SENSORS,
    SI_UNITS,
    TEMPERATURE_COLUMNS,
    TIME,
    column_values,
    temperature_column,
)
from imucal.segments.table import row_bounds, rows_of

#: The fewest poses a hold-out needs: one held out, at least two to fit on.
MIN_POSES = 3


@dataclass(frozen=True)
class PoseSeries:
    """The settled samples of one static pose.

    Attributes
    ----------
    label : str
    t_s : ndarray, shape (n,)
        Times, s.
    temp_c : ndarray, shape (n,)
        Temperature, deg C.
    values : dict of str to ndarray, shape (n, 3)
        Sensor -> readings (SI, sensor frame); rows with a NaN of any sensor or of the
        temperature are left out.
    """

    label: str
    t_s: np.ndarray
    temp_c: np.ndarray
    values: dict


def pose_series(
    table: pd.DataFrame, rows: pd.DataFrame, *, settle_s: float, sensors: Sequence[str]
) -> list[PoseSeries]:
    """The poses of a recording, each from ``settle_s`` after its start to its end.

    Parameters
    ----------
    table : DataFrame
        Ingested recording with a temperature column (:data:`imucal.columns.TEMPERATURE_COLUMNS`).
    rows : DataFrame
        Its static segments (rows of the segments table), one per pose.
    settle_s : float
        Time left out at the start of each pose (s): the handling's transient.
    sensors : sequence of str
        Sensors to keep (each must have its three columns).

    Returns
    -------
    list of PoseSeries

    Raises
    ------
    ValueError
        If the table has no temperature column or lacks a sensor's columns.
    """
    col = temperature_column(table)
    if col is None:
        raise ValueError(
            f"no temperature column in the recording (columns {list(table.columns)}); expected "
            "temp_c"
        )
    for s in sensors:
        missing = [c for c in SENSOR_COLUMNS[s] if c not in table.columns]
        if missing:
            raise ValueError(f"sensor {s!r}: columns {missing} not in the recording")
    t_all = table[TIME].to_numpy(dtype=float)
    out = []
    for (a, b), label in zip(row_bounds(rows), rows["label"].astype(str)):
        part = slice(a, b)
        t = t_all[part]
        temp = table[col].to_numpy(dtype=float)[part]
        values = {s: column_values(table, SENSOR_COLUMNS[s], part) for s in sensors}
        keep = (t >= t[0] + settle_s) & np.isfinite(temp) if len(t) else np.zeros(0, bool)
        for v in values.values():
            keep &= np.isfinite(v).all(axis=1)
        out.append(PoseSeries(label, t[keep], temp[keep], {s: v[keep] for s, v in values.items()}))
    return out


def _blocks(pose: PoseSeries, block_s: float) -> tuple[np.ndarray, dict]:
    """Means of consecutive ``block_s`` blocks (at least half full): temp (m,), sensor -> (m, 3)."""
    if not len(pose.t_s):
        return np.zeros(0), {s: np.zeros((0, 3)) for s in pose.values}
    k = ((pose.t_s - pose.t_s[0]) // block_s).astype(int)
    n = np.bincount(k)
    step = np.median(np.diff(pose.t_s)) if len(pose.t_s) > 1 else block_s
    full = n >= 0.5 * block_s / step
    temp = np.bincount(k, pose.temp_c)[full] / n[full]
    values = {
        s: np.column_stack([np.bincount(k, v[:, j])[full] / n[full] for j in range(3)])
        for s, v in pose.values.items()
    }
    return temp, values


def _powers(d_t: np.ndarray, order: int) -> np.ndarray:
    return (
        np.column_stack([d_t**q for q in range(1, order + 1)]) if order else np.zeros((len(d_t), 0))
    )


def fit_term(
    temps: Sequence[np.ndarray], values: Sequence[np.ndarray], order: int, reference_c: float
) -> np.ndarray:
    """Polynomial ``c_1 dT + .. + c_order dT^order`` with one constant per pose.

    Parameters
    ----------
    temps : sequence of ndarray, shape (m_p,)
        Temperatures (deg C) of each fit pose's blocks.
    values : sequence of ndarray, shape (m_p,)
        One axis's readings of the same blocks.
    order : int
    reference_c : float
        ``dT = T - reference_c``.

    Returns
    -------
    ndarray, shape (order,)
        ``c_1 .. c_order`` (unit of the readings per K^k); the constants are nuisance.
    """
    if order == 0:
        return np.zeros(0)
    sizes = [len(t) for t in temps]
    constants = np.zeros((sum(sizes), len(temps)))
    start = 0
    for p, m in enumerate(sizes):
        constants[start : start + m, p] = 1.0
        start += m
    d_t = np.concatenate(temps) - reference_c
    design = np.column_stack([constants, _powers(d_t, order)])
    coef, *_ = np.linalg.lstsq(design, np.concatenate(values), rcond=None)
    return coef[len(temps) :]


def _predict(coef: np.ndarray, temp: np.ndarray, reference_c: float) -> np.ndarray:
    return _powers(temp - reference_c, len(coef)) @ coef if len(coef) else np.zeros(len(temp))


def _centred(residual: np.ndarray) -> np.ndarray:
    return residual - residual.mean() if len(residual) else residual


def _span(temps: Sequence[np.ndarray], margin_c: float) -> tuple[float, float]:
    both = np.concatenate(temps)
    return float(both.min()) - margin_c, float(both.max()) + margin_c


def choose_order(
    squares: Mapping[int, Sequence[tuple[np.ndarray, np.ndarray]]],
) -> tuple[int, dict]:
    """The order of an axis's polynomial from its residuals on held-out poses.

    The order is the smallest whose mean squared held-out residual (over the samples of every
    held-out pose) is within one standard error of the best, as
    :func:`imucal.terms.temperature.select_model` chooses; order 0 (no term) when no polynomial
    predicts the held-out poses better by more than that. The residuals of a drift are
    correlated over minutes, so the standard error is that of a ratio over blocks (clusters):
    ``sqrt(sum_b (s_b - m n_b)^2) / sum_b n_b`` with ``s_b`` the sum of squares and ``n_b`` the
    samples of block ``b`` and ``m`` the mean.

    Parameters
    ----------
    squares : mapping of int to sequence of (ndarray, ndarray)
        Order -> per held-out pose, the sums of its squared residuals (constant removed) over
        consecutive blocks and the samples of each block, each shape (n_blocks,).

    Returns
    -------
    order : int
    heldout_rms : dict of int to float
        Order -> RMS over all held-out samples.
    """
    mean, se = {}, {}
    for k, pieces in squares.items():
        sums = np.concatenate([p[0] for p in pieces])
        counts = np.concatenate([p[1] for p in pieces])
        total = counts.sum()
        mean[k] = sums.sum() / total if total else np.nan
        se[k] = np.sqrt(np.sum((sums - mean[k] * counts) ** 2)) / total if total else np.nan
    heldout = {k: float(np.sqrt(v)) for k, v in mean.items()}
    if not np.isfinite(mean[0]):
        return 0, heldout
    best = min(mean, key=lambda k: mean[k])
    return min(k for k in mean if mean[k] <= mean[best] + se[best]), heldout


def _block_sums(x: np.ndarray, t_s: np.ndarray, block_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Sums of ``x`` (n,) over consecutive ``block_s`` blocks of ``t_s``, and their counts."""
    if not len(x):
        return x, x
    k = ((t_s - t_s[0]) // block_s).astype(int)
    n = np.bincount(k)
    return np.bincount(k, x)[n > 0], n[n > 0].astype(float)


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x**2))) if len(x) else float("nan")


def hold_out_poses(
    poses: Sequence[PoseSeries], *, block_s: float, max_order: int, margin_c: float
) -> dict:
    """Held-out residual RMS per pose x sensor x axis: no term, the project's term, regression.

    Parameters
    ----------
    poses : sequence of PoseSeries
        At least :data:`MIN_POSES` poses with samples, the same sensors each.
    block_s : float
        Block length (s) of the fits (block means), the order's standard error and the block
        comparison.
    max_order : int
        Highest polynomial order tried (>= 1).
    margin_c : float
        How far beyond the fit poses' temperature span (K) a held-out sample is compared.

    Returns
    -------
    dict
        ``cells``: one per held-out pose, sensor and axis, with ``held_out``, ``sensor``,
        ``axis``, ``unit``, ``samples`` (compared), ``fraction`` (of the pose's samples within
        the span), ``rms_none``, ``rms_term``, ``rms_regression`` (samples, constant removed),
        the same of the block means (``blocks_none`` ...), ``order`` (the axis's, chosen over
        all held-out poses), ``coef`` (``c_1 .. c_order``, unit per K^k), ``reference_c``,
        ``regression_slope`` (unit per K), ``paired`` (mean of ``r_term^2 - r_regression^2``
        over the samples and its standard error over blocks as in :func:`choose_order`,
        unit^2).
        ``orders``: per sensor and axis the chosen order and the held-out RMS of every order.
        ``summary``: per sensor and axis, the RMS over all held-out samples of each method and
        the ratios to none. ``poses``: label, samples, temperature span.

    Raises
    ------
    ValueError
        Fewer than :data:`MIN_POSES` poses with samples, or ``max_order < 1``.

    Notes
    -----
    The order of an axis is chosen on the same leave-one-pose-out residuals the table reports
    (as the term would be chosen for this recording). With ``max_order + 1`` candidates the
    choice adds little optimism; it removes a term from an axis where no order predicts the
    held-out poses better than none.
    """
    poses = [p for p in poses if len(p.t_s)]
    if len(poses) < MIN_POSES:
        raise ValueError(
            f"{len(poses)} static pose(s) with samples; holding one out needs at least {MIN_POSES}"
        )
    if max_order < 1:
        raise ValueError(f"max_order must be >= 1, got {max_order}")
    sensors = list(poses[0].values)
    blocks = [_blocks(p, block_s) for p in poses]
    folds = []
    for h, held in enumerate(poses):
        fit = [p for p in range(len(poses)) if p != h]
        lo, hi = _span([poses[p].temp_c for p in fit], margin_c)
        pooled_t = np.concatenate([poses[p].temp_c for p in fit])
        regressors = np.column_stack([np.ones_like(pooled_t), pooled_t])
        slopes = {
            s: np.linalg.lstsq(
                regressors, np.vstack([poses[p].values[s] for p in fit]), rcond=None
            )[0][1]
            for s in sensors
        }
        folds.append({
            "fit": fit, "reference_c": round(0.5 * (lo + hi), 2),
            "inside": (held.temp_c >= lo) & (held.temp_c <= hi),
            "block_in": (blocks[h][0] >= lo) & (blocks[h][0] <= hi), "slopes": slopes,
        })  # fmt: skip
    cells, orders = [], []
    for s in sensors:
        for j, axis in enumerate(AXES):
            coefs, squares = {}, {}
            for k in range(max_order + 1):
                coefs[k], squares[k] = [], []
                for h, (held, fold) in enumerate(zip(poses, folds)):
                    fit = fold["fit"]
                    coef = fit_term(
                        [blocks[p][0] for p in fit],
                        [blocks[p][1][s][:, j] for p in fit],
                        k,
                        fold["reference_c"],
                    )
                    inside = fold["inside"]
                    r = held.values[s][inside, j] - _predict(
                        coef, held.temp_c[inside], fold["reference_c"]
                    )
                    coefs[k].append(coef)
                    squares[k].append(_block_sums(_centred(r) ** 2, held.t_s[inside], block_s))
            order, heldout = choose_order(squares)
            orders.append({"sensor": s, "axis": axis, "order": order, "heldout_rms": heldout})
            for h, (held, fold) in enumerate(zip(poses, folds)):
                cells.append(_cell(held, blocks[h], fold, s, j, order, coefs[order][h], block_s))
    return {
        "poses": [
            {
                "label": p.label,
                "samples": len(p.t_s),
                "temp_span_c": [float(p.temp_c.min()), float(p.temp_c.max())],
            }
            for p in poses
        ],  # fmt: skip
        "orders": orders,
        "cells": cells,
        "summary": _summary(cells),
    }


def _cell(
    held: PoseSeries,
    block: tuple,
    fold: Mapping,
    sensor: str,
    j: int,
    order: int,
    coef: np.ndarray,
    block_s: float,
) -> dict:
    """One held-out pose, sensor and axis: the three methods' residual RMS."""
    inside, reference_c, slope = fold["inside"], fold["reference_c"], fold["slopes"][sensor][j]
    y, temp = held.values[sensor][inside, j], held.temp_c[inside]
    block_t, block_v = block
    yb, tb = block_v[sensor][fold["block_in"], j], block_t[fold["block_in"]]
    r_term = _centred(y - _predict(coef, temp, reference_c))
    r_reg = _centred(y - slope * temp)
    sums, counts = _block_sums(r_term**2 - r_reg**2, held.t_s[inside], block_s)
    diff = sums.sum() / counts.sum() if len(y) else float("nan")
    return {
        "held_out": held.label, "sensor": sensor, "axis": AXES[j], "unit": SI_UNITS[sensor],
        "samples": int(inside.sum()), "fraction": float(inside.mean()),
        "rms_none": _rms(_centred(y)), "rms_term": _rms(r_term), "rms_regression": _rms(r_reg),
        "blocks": int(fold["block_in"].sum()),
        "blocks_none": _rms(_centred(yb)),
        "blocks_term": _rms(_centred(yb - _predict(coef, tb, reference_c))),
        "blocks_regression": _rms(_centred(yb - slope * tb)),
        "order": order, "coef": coef.tolist(), "reference_c": reference_c,
        "regression_slope": float(slope),
        "paired": {
            "mean": float(diff),
            "se": float(np.sqrt(np.sum((sums - diff * counts) ** 2)) / counts.sum())
            if len(y) else float("nan"),
        },
    }  # fmt: skip


def _summary(cells: Sequence[Mapping]) -> list[dict]:
    """Per sensor and axis, the RMS over every held-out sample of each method."""
    out = []
    keys = dict.fromkeys((c["sensor"], c["axis"]) for c in cells)
    for sensor, axis in keys:
        group = [c for c in cells if c["sensor"] == sensor and c["axis"] == axis]
        n = np.array([c["samples"] for c in group], dtype=float)
        pooled = {
            m: float(np.sqrt(np.sum(n * np.array([c[f"rms_{m}"] for c in group]) ** 2) / n.sum()))
            for m in ("none", "term", "regression")
        }
        out.append({
            "sensor": sensor, "axis": axis, "unit": group[0]["unit"], **{f"rms_{m}": v for m, v in pooled.items()},
            "term_ratio": pooled["term"] / pooled["none"],
            "regression_ratio": pooled["regression"] / pooled["none"],
            "orders": [c["order"] for c in group],
        })  # fmt: skip
    return out


def holdout_recording(dataset) -> str | None:
    """The recording of a dataset with declared static poses and a temperature channel.

    Parameters
    ----------
    dataset : imucal.io.dataset.Dataset

    Returns
    -------
    str or None
        The first recording (in ``dataset.yaml`` order) whose reader declaration maps a
        temperature column (:data:`imucal.columns.TEMPERATURE_COLUMNS`) and for which
        ``segments:`` declares at least :data:`MIN_POSES` static poses; None when there is none
        (automatic segments are known only after the segmentation has run).
    """
    from imucal.io.readers import declared_entries

    for name, declaration in dataset.readers.items():
        targets = {t for e in declared_entries(declaration) for t in (e.get("columns") or {})}
        poses = [s for s in dataset.segments if s["recording"] == name and s["kind"] in POSE_KINDS]
        if targets & set(TEMPERATURE_COLUMNS) and len(poses) >= MIN_POSES:
            return name
    return None


def hold_out_recording(
    table: pd.DataFrame,
    segments: pd.DataFrame,
    *,
    recording: str,
    block_s: float,
    settle_s: float,
    max_order: int,
    margin_c: float,
) -> dict:
    """:func:`hold_out_poses` on the static poses of one ingested recording, with its settings.

    Parameters
    ----------
    table : DataFrame
        The ingested recording (SI units, a temperature column).
    segments : DataFrame
        The session's segments table; the recording's ``position`` and ``static`` rows are the
        poses.
    recording : str
    block_s, settle_s, max_order, margin_c : float, float, int, float
        See :func:`pose_series` and :func:`hold_out_poses`.

    Returns
    -------
    dict
        The result of :func:`hold_out_poses` with ``recording``, ``sensors`` and ``settings``.
    """
    sensors = [s for s in SENSORS if all(c in table.columns for c in SENSOR_COLUMNS[s])]
    rows = rows_of(segments, recording, *POSE_KINDS)
    poses = pose_series(table, rows, settle_s=settle_s, sensors=sensors)
    result = hold_out_poses(poses, block_s=block_s, max_order=max_order, margin_c=margin_c)
    settings = {"block_s": block_s, "settle_s": settle_s, "max_order": max_order,
                "margin_c": margin_c}  # fmt: skip
    return {"recording": recording, "sensors": sensors, "settings": settings, **result}
