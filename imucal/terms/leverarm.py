"""The accelerometer's lever arm from the rate table's rotation centre (frame B).

On a constant-rate plateau the accelerometer senses the specific force at the rotation centre
plus the centripetal acceleration ``w x (w x r) = (w w^T - |w|^2 I) r``; the tangential term
``dw/dt x r`` vanishes there. Each run's calibrated acc mean is therefore modelled as a
constant per table axis (gravity in B while the module is mounted for that axis; its part
across the axis turns with the table and averages out over whole turns) plus ``W r`` with
``W = w w^T - |w|^2 I`` from the run's calibrated gyro mean. The runs at every rate of one
axis (rest runs included) are stacked and solved by least squares.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from imucal.columns import AXES
from imucal.gap import session as st
from imucal.modelterms.leverarm import LeverArm
from imucal.pipeline.full import SessionFit, calibrated

METHOD = (
    "calibrated acc means of the rate-table plateaus against w w^T - |w|^2 I (w the run's "
    "calibrated gyro mean), a constant per table axis"
)


def table_runs(fit: SessionFit, half: str | None = None) -> pd.DataFrame | None:
    """The rate-table runs the gyroscope fit kept (rest runs included), of one half of the
    rate levels (:func:`imucal.gap.session.run_half`) or all; None without a table."""
    table = fit.artifacts["gyr_table"]
    if table is None or "ratetable" not in fit.imu:
        return None
    rows = st.segment_rows(fit, "ratetable", "run")
    keep = rows["label"].isin(table["labels"]) | (rows["rate_dps"] == 0)
    return st.run_half(rows[keep], half)


def _design(fit: SessionFit, rows: pd.DataFrame, lever: bool) -> tuple[np.ndarray, np.ndarray]:
    """Stacked design (3 r, 9 + 3) and observations (3 r,) of the run means (m/s^2)."""
    acc = st.segment_means(calibrated(fit, "ratetable", "acc"), rows)
    w = st.segment_means(calibrated(fit, "ratetable", "gyr"), rows)
    axis = [AXES.index(a) for a in rows["axis"]]
    blocks = []
    for i in range(len(rows)):
        const = np.zeros((3, 9))
        const[:, 3 * axis[i] : 3 * axis[i] + 3] = np.eye(3)
        cols = [const]
        if lever:
            cols.append(np.outer(w[i], w[i]) - (w[i] @ w[i]) * np.eye(3))
        blocks.append(np.hstack(cols))
    x = np.vstack(blocks) if blocks else np.zeros((0, 12 if lever else 9))
    y = acc.reshape(-1)
    ok = np.isfinite(y) & np.all(np.isfinite(x), axis=1)
    return x[ok], y[ok]


def _solve(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Least squares with the columns no run touches (an axis without runs) left at zero."""
    used = np.any(x != 0, axis=0)
    coef = np.zeros(x.shape[1])
    std = np.zeros(x.shape[1])
    sol, *_ = np.linalg.lstsq(x[:, used], y, rcond=None)
    dof = max(len(y) - int(used.sum()), 1)
    sigma2 = float(np.sum((y - x[:, used] @ sol) ** 2) / dof)
    coef[used] = sol
    std[used] = np.sqrt(
        np.clip(np.diag(np.linalg.pinv(x[:, used].T @ x[:, used])), 0, None) * sigma2
    )
    return coef, std


def heldout_table_rms(fit: SessionFit) -> dict:
    """RMS (m/s^2) of the calibrated acc means of the runs of half B of the rate levels,
    predicted by a fit on half A, without and with the lever arm (rest runs in both halves);
    ``values``: how many run-mean components the RMS is over."""
    out = {}
    rows_a, rows_b = table_runs(fit, "A"), table_runs(fit, "B")
    moving_b = rows_b[rows_b["rate_dps"] != 0]
    for name, lever in (("without", False), ("with", True)):
        coef, _ = _solve(*_design(fit, rows_a, lever))
        x, y = _design(fit, moving_b, lever)
        out[name] = float(np.sqrt(np.mean((y - x @ coef) ** 2))) if len(y) else float("nan")
    out["values"] = len(y)
    return out


def fit_lever_arm(fit: SessionFit) -> tuple[LeverArm | None, dict]:
    """``r`` of the accelerometer from the rate-table runs (least squares, standard deviations
    with the residual variance of the run means).

    Parameters
    ----------
    fit : SessionFit
        The session calibrated with the paper's model.

    Returns
    -------
    term : LeverArm or None
        None without a rate table or when its turning runs do not span two table axes (one
        axis sees only the components of ``r`` across it).
    evidence : dict
        ``heldout_rms`` (``without``, ``with``: the runs of half the rate levels predicted from
        the other half, m/s^2), ``runs``, ``axes``, or ``refused``.
    """
    rows = table_runs(fit)
    if rows is None:
        return None, {"refused": "the session has no rate-table recording with a gyroscope fit"}
    turning = rows[rows["rate_dps"] != 0]
    axes = sorted(set(turning["axis"]))
    if len(axes) < 2:
        return None, {
            "refused": f"rate-table runs about {axes or 'no axis'}: the lever arm along a table "
            "axis needs runs about two axes"
        }
    x, y = _design(fit, rows, lever=True)
    coef, std = _solve(x, y)
    evidence = {
        "heldout_rms": heldout_table_rms(fit),
        "unit": "m/s^2 (rate-table run means)",
        "runs": len(rows),
        "axes": axes,
    }
    return LeverArm(coef[9:], std[9:], METHOD), evidence
