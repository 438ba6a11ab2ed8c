"""Figures of the accelerometer and gyroscope fits (the paper's Figs. 10, 15, 16-17)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from matplotlib.figure import Figure

from imucal.columns import AXES
from imucal.fits.accelerometer import CubeFit
from imucal.fits.ratetable import RateTableFit

#: Okabe-Ito colours (colour-blind safe): before / after, and per axis.
BEFORE_COLOUR = "#E69F00"
AFTER_COLOUR = "#0072B2"
AXIS_COLOURS = {"x": "#D55E00", "y": "#0072B2", "z": "#000000"}


def plot_before_after_errors(
    labels: Sequence[str],
    before: np.ndarray,
    after: np.ndarray,
    unit: str,
    title: str,
    quantity: str = "|v| - reference",
) -> Figure:
    """Per-item errors before and after a calibration (absolute, log scale; signed after).

    Parameters
    ----------
    labels : sequence of str, length n
    before, after : array_like, shape (n,)
        Errors in ``unit``.
    unit : str
    title : str
    quantity : str
        What the error is, for the axis labels.
    """
    before, after = np.asarray(before, dtype=float), np.asarray(after, dtype=float)
    if not len(labels) == len(before) == len(after):
        raise ValueError(
            f"{len(labels)} labels for {len(before)} and {len(after)} errors; expected equal"
        )
    fig = Figure(figsize=(8, 5.5), layout="constrained")
    top, bottom = fig.subplots(2, 1, sharex=True)
    x = np.arange(len(labels))
    top.bar(x - 0.2, np.abs(before), 0.4, color=BEFORE_COLOUR, label="uncalibrated")
    top.bar(x + 0.2, np.abs(after), 0.4, color=AFTER_COLOUR, label="calibrated")
    top.set_ylabel(f"|{quantity}|  ({unit})")
    top.set_yscale("log")
    top.legend(loc="upper right")
    top.set_title(title)
    # the calibrated residuals on their own linear scale, with sign
    bottom.bar(x, after, 0.6, color=AFTER_COLOUR)
    bottom.axhline(0, color="0.5", lw=0.8)
    bottom.set_ylabel(f"calibrated: {quantity}  ({unit})")
    bottom.set_xticks(x, labels, rotation=90 if len(labels) > 14 else 0)
    return fig


def plot_cube_magnitude_errors(fit: CubeFit) -> Figure:
    """Norm error ``|a| - g`` per cube position before and after the cube fit (Fig. 10).

    Parameters
    ----------
    fit : CubeFit

    Returns
    -------
    matplotlib.figure.Figure
        Top: absolute error (log scale) before and after; bottom: signed error after, m/s^2.
    """
    return plot_before_after_errors(
        fit.labels,
        fit.magnitude_error_before_m_s2,
        fit.magnitude_error_after_m_s2,
        "m/s^2",
        f"Accelerometer cube fit (eq. 32, {fit.method}): |a| - g per position",
    )


def plot_rate_table_errors(fit: RateTableFit, labels: Sequence[str]) -> Figure:
    """Norm error ``|w| - |w_true|`` per rate-table run before and after (Fig. 15).

    Parameters
    ----------
    fit : RateTableFit
    labels : sequence of str, length n_runs
        Run labels (e.g. ``x-400``), in the order of the fit's runs.

    Returns
    -------
    matplotlib.figure.Figure
        Errors in deg/s: top absolute (log scale) before and after, bottom signed after.
    """
    if len(labels) != len(fit.magnitude_error_before_rad_s):
        raise ValueError(
            f"{len(labels)} labels for {len(fit.magnitude_error_before_rad_s)} runs; "
            "expected one label per run"
        )
    return plot_before_after_errors(
        labels,
        np.degrees(fit.magnitude_error_before_rad_s),
        np.degrees(fit.magnitude_error_after_rad_s),
        "deg/s",
        "Gyroscope rate table (eq. 33): |w| - |w_true| per run",
    )


def plot_gyro_bias(t_s: np.ndarray, rate_rad_s: np.ndarray, bias_rad_s: np.ndarray) -> Figure:
    """Static gyro rate before and after bias removal (Figs. 16-17).

    Parameters
    ----------
    t_s : ndarray, shape (n,)
        Timestamps, s.
    rate_rad_s : ndarray, shape (n, 3)
        Raw static gyro rate, rad/s.
    bias_rad_s : ndarray, shape (3,)
        The estimated bias, rad/s.

    Returns
    -------
    matplotlib.figure.Figure
        Two panels sharing the time axis, rates in deg/s.
    """
    t = np.asarray(t_s, dtype=float)
    w = np.asarray(rate_rad_s, dtype=float)
    if t.ndim != 1 or w.shape != (len(t), 3):
        raise ValueError(f"expected t_s (n,) and rate_rad_s (n, 3), got {t.shape} and {w.shape}")
    bias = np.asarray(bias_rad_s, dtype=float).reshape(3)
    fig = Figure(figsize=(8, 5.5), layout="constrained")
    top, bottom = fig.subplots(2, 1, sharex=True)
    for k, axis in enumerate(AXES):
        colour = AXIS_COLOURS[axis]
        top.plot(t, np.degrees(w[:, k]), color=colour, lw=0.5, label=f"gyr_{axis}")
        top.axhline(np.degrees(bias[k]), color=colour, ls="--", lw=1)
        bottom.plot(t, np.degrees(w[:, k] - bias[k]), color=colour, lw=0.5, label=f"gyr_{axis}")
    top.set_title("Gyroscope at rest before bias removal (dashed: estimated bias)")
    top.set_ylabel("rate (deg/s)")
    fig.legend(*top.get_legend_handles_labels(), loc="outside right upper")
    bottom.set_title("after bias removal")
    bottom.axhline(0, color="0.5", lw=0.8)
    bottom.set_ylabel("rate (deg/s)")
    bottom.set_xlabel("time (s)")
    return fig


def plot_phases_before_after(
    phases: Mapping[str, tuple[np.ndarray, np.ndarray, np.ndarray]],
    *,
    unit: str,
    factor: float = 1.0,
    quantity: str,
    title: str,
) -> Figure:
    """The rotation3d phases of one sensor before and after alignment (Figs. 11-13, 18-19).

    In the phase about axis ``k`` of frame B the component along ``k`` is the one the alignment
    makes constant (accelerometer: the gravity component along the rotation axis; gyroscope: the
    whole rate lies on ``k``, so the other two components vanish after alignment).

    Parameters
    ----------
    phases : mapping of str to (ndarray (n,), ndarray (n, 3), ndarray (n, 3))
        Phase label ('x', 'y', 'z') -> (timestamps in s, values before alignment, values after),
        values in SI units.
    unit : str
        Unit label of the plotted values (after ``factor``).
    factor : float
        Multiplies the SI values for display (e.g. ``180 / pi`` for deg/s).
    quantity : str
        Axis label, e.g. 'specific force'.
    title : str

    Returns
    -------
    matplotlib.figure.Figure
        One row per phase, columns 'before' and 'after' sharing the y axis of the row.
    """
    if not phases:
        raise ValueError("no phase to plot; expected at least one of the phases x, y, z")
    fig = Figure(figsize=(9, 2.4 * len(phases) + 0.8), layout="constrained")
    grid = fig.subplots(len(phases), 2, sharey="row", squeeze=False)
    for row, (label, (t, before, after)) in zip(grid, sorted(phases.items())):
        t = np.asarray(t, dtype=float)
        for ax, values, when in zip(row, (before, after), ("before", "after")):
            values = np.asarray(values, dtype=float)
            if values.shape != (len(t), 3):
                raise ValueError(
                    f"phase {label!r}: expected values of shape ({len(t)}, 3), got {values.shape}"
                )
            for k, axis in enumerate(AXES):
                ax.plot(
                    t - t[0],
                    values[:, k] * factor,
                    color=AXIS_COLOURS[axis],
                    lw=0.8,
                    label=f"{axis}_B",
                )
            ax.axhline(0, color="0.6", lw=0.6)
            ax.set_title(f"phase {label}: {when} alignment", fontsize="medium")
            ax.set_ylabel(f"{quantity} ({unit})")
        row[0].set_xlabel("time in phase (s)")
        row[1].set_xlabel("time in phase (s)")
    fig.legend(*grid[0, 0].get_legend_handles_labels(), loc="outside right upper")
    fig.suptitle(title)
    return fig
