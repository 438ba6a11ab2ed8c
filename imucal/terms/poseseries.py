"""The static poses of a thermal recording, and the temperature term fitted and chosen on them.

The pieces of the pose hold-out (:mod:`imucal.terms.poseholdout`) that concern one pose or one
fit: a pose's settled samples (:class:`PoseSeries`) and their block means, the term's
polynomial with one constant per pose (:func:`fit_term`), its residual on a held-out pose, and
the choice of its order on poses it did not see (:func:`choose_order`, :func:`nested_order`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from imucal.columns import SENSOR_COLUMNS, TIME, column_values, temperature_column
from imucal.segments.table import row_bounds
from imucal.terms.blockspread import block_index, block_sums, cluster_mean


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


def pose_blocks(pose: PoseSeries, block_s: float) -> tuple[np.ndarray, dict, np.ndarray]:
    """Means of consecutive ``block_s`` blocks (at least half full): temp (m,), sensor -> (m, 3),
    and each block's start (s after the pose's first sample, (m,))."""
    if not len(pose.t_s):
        return np.zeros(0), {s: np.zeros((0, 3)) for s in pose.values}, np.zeros(0)
    k = block_index(pose.t_s, block_s, pose.t_s[0])
    n = np.bincount(k)
    step = np.median(np.diff(pose.t_s)) if len(pose.t_s) > 1 else block_s
    full = n >= 0.5 * block_s / step
    temp = np.bincount(k, pose.temp_c)[full] / n[full]
    values = {
        s: np.column_stack([np.bincount(k, v[:, j])[full] / n[full] for j in range(3)])
        for s, v in pose.values.items()
    }
    return temp, values, np.flatnonzero(full) * block_s


def powers(d_t: np.ndarray, order: int) -> np.ndarray:
    return (
        np.column_stack([d_t**q for q in range(1, order + 1)]) if order else np.zeros((len(d_t), 0))
    )


def term_design(temps: Sequence[np.ndarray], order: int, reference_c: float) -> np.ndarray:
    """Design of :func:`fit_term`: one constant column per pose, then ``dT .. dT^order``."""
    sizes = [len(t) for t in temps]
    constants = np.zeros((sum(sizes), len(temps)))
    start = 0
    for p, m in enumerate(sizes):
        constants[start : start + m, p] = 1.0
        start += m
    return np.column_stack([constants, powers(np.concatenate(temps) - reference_c, order)])


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
    coef, *_ = np.linalg.lstsq(
        term_design(temps, order, reference_c), np.concatenate(values), rcond=None
    )
    return coef[len(temps) :]


def predict_term(coef: np.ndarray, temp: np.ndarray, reference_c: float) -> np.ndarray:
    return powers(temp - reference_c, len(coef)) @ coef if len(coef) else np.zeros(len(temp))


def centred(residual: np.ndarray) -> np.ndarray:
    return residual - residual.mean() if len(residual) else residual


def temperature_span(temps: Sequence[np.ndarray], margin_c: float) -> tuple[float, float]:
    both = np.concatenate(temps)
    return float(both.min()) - margin_c, float(both.max()) + margin_c


def choose_order(
    squares: Mapping[int, Sequence[tuple[np.ndarray, np.ndarray]]],
) -> tuple[int, dict]:
    """The order of an axis's polynomial from its residuals on poses its fit did not see.

    Two steps. A polynomial is a law of the part, so an order ``k >= 1`` is admissible only if
    it predicts every held-out pose better than no term, each by more than one standard error
    of the paired difference (the orders are compared on the same samples, which share the
    white noise and the pose's own drift); with no admissible order the axis gets none (0).
    A held-out pose whose compared samples lie in a single block (one that overlaps the
    others' temperature span only briefly) has no standard error and can neither confirm nor
    refute an order: it is left out of this test, which needs at least two poses that can.
    Among the admissible orders the choice is the smallest whose mean squared held-out residual
    (over the samples of every held-out pose) is within one standard error of the best's, the
    one-standard-error rule of :func:`imucal.gap.temperature.select_model`. The residuals of
    a drift are correlated over hours, so each standard error is that of a ratio over long
    blocks (clusters, :func:`~imucal.terms.blockspread.cluster_mean`).

    Parameters
    ----------
    squares : mapping of int to sequence of (ndarray, ndarray)
        Order (0 = no term) -> per held-out pose, the sums of its squared residuals (constant
        removed) over consecutive blocks and the samples of each block, each shape
        (n_blocks,); the same blocks for every order.

    Returns
    -------
    order : int
    heldout_rms : dict of int to float
        Order -> RMS over all held-out samples.
    """

    pooled = {
        k: cluster_mean(*(np.concatenate([p[i] for p in pieces]) for i in (0, 1)))
        for k, pieces in squares.items()
    }
    heldout = {k: float(np.sqrt(m)) for k, (m, _) in pooled.items()}
    admissible = []
    for k in squares:
        gains = [cluster_mean(p[0] - q[0], p[1]) for p, q in zip(squares[k], squares[0])]
        judged = [(m, se) for m, se in gains if np.isfinite(se)]
        if k and len(judged) >= 2 and all(m + se < 0 for m, se in judged):
            admissible.append(k)
    if not admissible:
        return 0, heldout
    best = min(admissible, key=lambda k: pooled[k][0])
    return min(k for k in admissible if pooled[k][0] <= sum(pooled[best])), heldout


def rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x**2))) if len(x) else float("nan")


def heldout_residual(poses, blocks, fit, held, inside, sensor, j, order, margin_c) -> tuple:
    """The term of ``order`` fitted on the poses ``fit`` (indices), its residual on ``held``'s
    samples ``inside`` (constant not removed) and the term's coefficients and reference."""
    lo, hi = temperature_span([poses[p].temp_c for p in fit], margin_c)
    reference_c = round(0.5 * (lo + hi), 2)
    coef = fit_term(
        [blocks[p][0] for p in fit], [blocks[p][1][sensor][:, j] for p in fit], order, reference_c
    )
    y = held.values[sensor][inside, j]
    return y - predict_term(coef, held.temp_c[inside], reference_c), coef, reference_c


def inside_span(poses: Sequence[PoseSeries], fit: Sequence[int], held: int, margin_c: float):
    lo, hi = temperature_span([poses[p].temp_c for p in fit], margin_c)
    return (poses[held].temp_c >= lo) & (poses[held].temp_c <= hi)


def nested_order(
    poses: Sequence[PoseSeries],
    blocks: Sequence[tuple],
    fit: Sequence[int],
    sensor: str,
    j: int,
    *,
    max_order: int,
    margin_c: float,
    se_block_s: float,
) -> tuple[int, dict]:
    """The order of one axis chosen on the fit poses alone: each held out from the others.

    Each pose of ``fit`` is predicted from the other fit poses (its constant removed, within
    their span widened by ``margin_c``) for every order ``0 .. max_order``;
    :func:`choose_order` picks on these residuals. The pose held out of the whole comparison
    takes no part, so its residual is an honest test of the choice too.

    Parameters
    ----------
    poses : sequence of PoseSeries
    blocks : sequence of (ndarray, dict)
        Each pose's block means (temperature, sensor -> (m, 3)), as the term is fitted.
    fit : sequence of int
        Indices of the fit poses (at least two).
    sensor : str
    j : int
        Axis index.
    max_order : int
    margin_c : float
        K.
    se_block_s : float
        Block length (s) of the standard error of :func:`choose_order`.

    Returns
    -------
    order : int
    inner_rms : dict of int to float
        Order -> RMS over the fit poses, each predicted from the others.
    """
    squares = {k: [] for k in range(max_order + 1)}
    for i in fit:
        rest = [p for p in fit if p != i]
        inside = inside_span(poses, rest, i, margin_c)
        for k in squares:
            r = heldout_residual(poses, blocks, rest, poses[i], inside, sensor, j, k, margin_c)[0]
            squares[k].append(block_sums(centred(r) ** 2, poses[i].t_s[inside], se_block_s))
    return choose_order(squares)
