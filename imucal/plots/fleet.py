"""Figures of a fleet: each parameter across units, and each unit's biases over time."""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from imucal.columns import AXES, SENSORS
from imucal.fleet.summary import PARAMETERS
from imucal.plots.style import MIN_FONT_PT, PAGE_WIDTH_IN


def plot_fleet_parameters(scores: pd.DataFrame) -> Figure:
    """Each parameter of each sensor across units (latest sessions), outliers in red.

    Parameters
    ----------
    scores : DataFrame
        :func:`imucal.fleet.flag_outliers` (one row per unit and parameter axis).

    Returns
    -------
    Figure
        Rows: sensors; columns: bias, scale, xi, alpha; x: axis; the fleet's median as a bar.
    """
    fig = Figure(figsize=(PAGE_WIDTH_IN, 7.5), layout="constrained")
    axes = fig.subplots(len(SENSORS), len(PARAMETERS), squeeze=False)
    rng = np.random.default_rng(0)  # jitter only, for legibility
    for i, sensor in enumerate(SENSORS):
        for j, parameter in enumerate(PARAMETERS):
            ax = axes[i][j]
            rows = scores[(scores["sensor"] == sensor) & (scores["parameter"] == parameter)]
            ax.set_title(f"{sensor} {parameter}", fontsize=9)
            ax.set_xticks(range(3), AXES)
            if rows.empty:
                ax.text(0.5, 0.5, "not calibrated", ha="center", transform=ax.transAxes)
                continue
            for k, axis in enumerate(AXES):
                r = rows[rows["axis"] == axis]
                x = k + rng.uniform(-0.15, 0.15, len(r))
                bad = r["outlier"].to_numpy(dtype=bool)
                ax.plot(x[~bad], r["value"][~bad], ".", color="tab:blue", ms=4)
                ax.plot(x[bad], r["value"][bad], "o", color="tab:red", ms=5)
                for xx, (_, o) in zip(x[bad], r[bad].iterrows(), strict=True):
                    ax.annotate(
                        str(o["serial"]),
                        (xx, o["value"]),
                        fontsize=MIN_FONT_PT + 0.5,
                        color="tab:red",
                    )
                if len(r):
                    ax.hlines(r["median"].iloc[0], k - 0.3, k + 0.3, color="k", lw=1)
            ax.tick_params(labelsize=7)
    fig.suptitle("Parameters across units (latest session each; red: outliers)", fontsize=10)
    return fig


def plot_bias_over_time(table: pd.DataFrame) -> Figure:
    """Each unit's bias per sensor and axis over its sessions.

    Parameters
    ----------
    table : DataFrame
        :func:`imucal.fleet.parameter_table`.

    Returns
    -------
    Figure
        Rows: sensors; columns: axes; one line per unit with two or more sessions.
    """
    fig = Figure(figsize=(PAGE_WIDTH_IN, 7), layout="constrained")
    axes = fig.subplots(len(SENSORS), 3, squeeze=False, sharex=True)
    bias = table[table["parameter"] == "bias"]
    for i, sensor in enumerate(SENSORS):
        for k, axis in enumerate(AXES):
            ax = axes[i][k]
            rows = bias[(bias["sensor"] == sensor) & (bias["axis"] == axis)]
            for _, unit in rows.sort_values("date").groupby("serial"):
                if len(unit) > 1:
                    ax.plot(unit["date"], unit["value"], ".-", lw=0.8, ms=3)
            unit_label = rows["unit"].iloc[0] if len(rows) else ""
            ax.set_title(f"{sensor} bias {axis} ({unit_label})", fontsize=9)
            ax.tick_params(labelsize=7)
    fig.suptitle("Bias of each unit over its calibrations", fontsize=10)
    return fig
