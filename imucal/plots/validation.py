"""Figures of the validation against the reference IMU (return a Figure, never save or show)."""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from imucal.columns import SENSOR_COLUMNS, SENSORS, SI_UNITS, TIME
from imucal.plots.style import PAGE_WIDTH_IN
from imucal.validation import TimeAlignment, correlate_offsets

_TITLES = {"acc": "accelerometer", "gyr": "gyroscope", "mag": "magnetometer"}


def _norm(table: pd.DataFrame, sensor: str) -> np.ndarray:
    return np.linalg.norm(table[list(SENSOR_COLUMNS[sensor])].to_numpy(dtype=float), axis=1)


def plot_magnitudes(
    module_raw: pd.DataFrame, module: pd.DataFrame, reference_aligned: pd.DataFrame
) -> Figure:
    """Magnitudes of module (raw and calibrated) and reference over time, as Fig. 20.

    Parameters
    ----------
    module_raw, module : DataFrame
        The module recording before and after calibration (same rows).
    reference_aligned : DataFrame
        :func:`imucal.validation.align_reference` at the module's rows; its ``t_s`` (module
        packet times, s) is the time axis.

    Returns
    -------
    Figure
        Three panels (acc, gyr, mag). The magnetometer is drawn only at the module's own 10 Hz
        sample times, as markers.
    """
    if not (len(module_raw) == len(module) == len(reference_aligned)):
        raise ValueError(
            f"expected tables of equal length, got {len(module_raw)}, {len(module)}, "
            f"{len(reference_aligned)} rows"
        )
    t = reference_aligned[TIME].to_numpy(dtype=float)
    fig = Figure(figsize=(PAGE_WIDTH_IN, 8), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    for ax, sensor in zip(axes, SENSORS):
        ref, raw, cal = (_norm(x, sensor) for x in (reference_aligned, module_raw, module))
        style = {"marker": ".", "linestyle": "none", "markersize": 3} if sensor == "mag" else {}
        rows = np.isfinite(raw) if sensor == "mag" else np.ones(t.size, dtype=bool)
        ax.plot(t[rows], raw[rows], color="0.7", label="module, raw", **style)
        ax.plot(t[rows], cal[rows], color="C0", label="module, calibrated", **style)
        ax.plot(t, ref, color="k", linewidth=0.8, label="reference")
        ax.set_ylabel(f"|{sensor}| ({SI_UNITS[sensor]})")
        ax.set_title(_TITLES[sensor], loc="left")
    axes[0].legend(loc="best")
    axes[-1].set_xlabel("module time (s)")
    return fig


def plot_cross_correlation(
    t_module: np.ndarray,
    gyr_module: np.ndarray,
    t_reference: np.ndarray,
    gyr_reference: np.ndarray,
    alignment: TimeAlignment,
    span_s: float = 0.05,
) -> Figure:
    """Correlation of ``|omega|^2`` around the estimated offset, and the windowed offsets.

    Parameters
    ----------
    t_module, gyr_module, t_reference, gyr_reference
        As for :func:`imucal.validation.estimate_time_alignment` (s, rad/s).
    alignment : TimeAlignment
    span_s : float
        Half width of the offset range drawn, s.

    Returns
    -------
    Figure
        Left: correlation coefficient against the offset (at the estimated drift), the estimate
        and its 1-sigma band. Right: offsets fitted in windows against module time and the
        fitted line ``offset + drift * t``.
    """
    if span_s <= 0:
        raise ValueError(f"span_s must be > 0, got {span_s}")
    offsets = alignment.offset_s + np.linspace(-span_s, span_s, 201)
    rho = correlate_offsets(
        t_module, gyr_module, t_reference, gyr_reference, offsets, alignment.drift_ppm
    )
    fig = Figure(figsize=(PAGE_WIDTH_IN, 4), layout="constrained")
    left, right = fig.subplots(1, 2)
    rel_ms = (offsets - alignment.offset_s) * 1e3
    left.plot(rel_ms, rho, color="C0")
    left.axvline(0.0, color="k", linewidth=0.8)
    left.axvspan(-alignment.offset_std_s * 1e3, alignment.offset_std_s * 1e3, color="C1", alpha=0.3)
    left.set_xlabel(f"offset - {alignment.offset_s:.4f} s (ms)")
    left.set_ylabel("correlation of |omega|^2")

    t = np.asarray(t_module, dtype=float)
    line_t = np.array([t.min(), t.max()])
    line = alignment.offset_s + alignment.drift_ppm * 1e-6 * line_t
    right.plot(
        line_t,
        (line - alignment.offset_mid_s) * 1e3,
        color="k",
        linewidth=0.8,
        label=f"drift {alignment.drift_ppm:.1f} +- {alignment.drift_std_ppm:.1f} ppm",
    )
    right.plot(
        alignment.window_t_s,
        (alignment.window_offset_s - alignment.offset_mid_s) * 1e3,
        "o",
        color="C0",
        label="windows",
    )
    right.set_xlabel("module time (s)")
    right.set_ylabel(f"offset - {alignment.offset_mid_s:.4f} s (ms)")
    right.legend(loc="best")
    return fig
