"""Figure of one recording with its segments shaded and labelled."""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from imucal.columns import ACC, AXES, GYR, MAG, TIME
from imucal.plots.style import MIN_FONT_PT, PAGE_WIDTH_IN

#: Font size of the segments' labels and the legends (pt).
LABEL_PT = max(MIN_FONT_PT, 7.5)
#: Share of the figure's width the time axis takes (the legends sit to its right).
AXIS_SHARE = 0.76
#: Width of a character of the labels over the font size (DejaVu Sans, with a margin).
CHAR_EM = 0.62
#: Lanes of horizontal labels above the top panel before they are turned upright.
MAX_LANES = 3

#: Okabe-Ito colours (colour-blind safe) per segment kind and per axis.
KIND_COLOURS = {
    "static": "#999999",
    "phase": "#E69F00",
    "transition": "#CC79A7",
    "position": "#56B4E9",
    "run": "#009E73",
}
AXIS_COLOURS = {"x": "#D55E00", "y": "#0072B2", "z": "#000000"}


def plot_segments(
    table: pd.DataFrame, segments: pd.DataFrame, recording: str | None = None, title: str = ""
) -> Figure:
    """Raw gyro rate and specific force over time with the recording's segments shaded.

    Parameters
    ----------
    table : DataFrame
        Ingested recording (``t_s`` and any of ``gyr_*`` in rad/s, ``acc_*`` in m/s^2,
        ``mag_*``; NaN where a merged stream has no sample of that sensor).
    segments : DataFrame
        Segments table (``recording``, ``label``, ``kind``, ``start_s``, ``end_s``, ``turns``).
    recording : str, optional
        Plot only the segments of this recording; all rows when None.
    title : str
        Figure title (e.g. "dataset / recording").

    Returns
    -------
    matplotlib.figure.Figure
        One panel per sensor present, sharing the time axis: gyro axes and norm in deg/s,
        accelerometer axes in m/s^2, magnetometer (normalised). Segments are shaded by kind and labelled at the top (phases and transitions with
        their raw turns).
    """
    if TIME not in table.columns:
        raise ValueError(f"recording lacks the column {TIME!r}; expected the ingested layout")
    panels = [
        (sensor, cols, factor, label)
        for sensor, cols, factor, label in (
            ("gyr", GYR, np.degrees(1.0), "raw rate (deg/s)"),
            ("acc", ACC, 1.0, "raw specific force (m/s$^2$)"),
            ("mag", MAG, 1.0, "raw field (normalised)"),
        )
        if all(c in table.columns for c in cols)
    ]
    if not panels:
        raise ValueError(
            f"recording has none of the sensor columns {[*GYR, *ACC, *MAG]}; nothing to plot"
        )
    if recording is not None:
        segments = segments[segments["recording"] == recording]
    fig = Figure(figsize=(PAGE_WIDTH_IN, 2.4 + 2.2 * len(panels)), layout="constrained")
    axes = fig.subplots(len(panels), 1, sharex=True, squeeze=False)[:, 0]
    for ax, (sensor, cols, factor, label) in zip(axes, panels):
        values = table[list(cols)].to_numpy(dtype=float) * factor
        fresh = np.isfinite(values).all(axis=1)  # merged streams: this sensor's own rows
        t = table[TIME].to_numpy(dtype=float)[fresh]
        values = values[fresh]
        for k, axis in enumerate(AXES):
            ax.plot(t, values[:, k], lw=0.7, color=AXIS_COLOURS[axis], label=f"{sensor} {axis}")
        if sensor == "gyr":
            ax.plot(
                t, np.linalg.norm(values, axis=1), lw=0.7, ls="--", color="#999999", label="|gyr|"
            )
        ax.set_ylabel(label)
    ax_g, ax_a = axes[0], axes[-1]
    seen = set()
    labels = []
    for row in segments.itertuples(index=False):
        colour = KIND_COLOURS.get(row.kind, "#999999")
        for ax in axes:
            ax.axvspan(
                row.start_s,
                row.end_s,
                color=colour,
                alpha=0.25,
                lw=0,
                label=row.kind if ax is ax_a and row.kind not in seen else None,
            )
        seen.add(row.kind)
        text = row.label
        if row.kind in ("phase", "transition") and np.isfinite(row.turns):
            text += f"\n{row.turns:+.2f} turns"
        labels.append(((row.start_s + row.end_s) / 2, text))
    span = (float(np.nanmin(table[TIME])), float(np.nanmax(table[TIME])))
    for (centre, text), (dy, rotation) in zip(labels, _label_lanes(labels, span), strict=True):
        ax_g.annotate(text, (centre, 1.0), xycoords=("data", "axes fraction"),
                      xytext=(0, dy), textcoords="offset points", ha="center", va="bottom",
                      fontsize=LABEL_PT, rotation=rotation)  # fmt: skip
    ax_a.set_xlabel("time (s)")
    for ax in axes:
        ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=LABEL_PT)
    if title:
        fig.suptitle(title)
    return fig


def _label_lanes(labels: list[tuple[float, str]], span: tuple[float, float]) -> list[tuple]:
    """Where each segment label goes above the top panel so that no two overlap: the lane's
    offset (points) and the rotation, in the order given. Labels side by side share a lane;
    one that would touch its neighbour goes a lane up; past :data:`MAX_LANES` lanes every
    label is turned upright (its width is then its lines' height)."""
    width_s = (span[1] - span[0]) or 1.0
    axis_pt = AXIS_SHARE * PAGE_WIDTH_IN * 72.0
    line_pt = 1.25 * LABEL_PT

    def lanes(extent) -> list[int]:
        ends: list[float] = []
        out = [0] * len(labels)
        for i in sorted(range(len(labels)), key=lambda k: labels[k][0]):
            centre, text = labels[i]
            half = extent(text) / axis_pt * width_s / 2
            lane = next((k for k, end in enumerate(ends) if end <= centre - half), len(ends))
            if lane == len(ends):
                ends.append(0.0)
            ends[lane] = centre + half
            out[i] = lane
        return out

    flat = lanes(lambda t: CHAR_EM * LABEL_PT * max(len(line) for line in t.split("\n")) + 4)
    if max(flat, default=0) < MAX_LANES:
        height = max((t.count("\n") + 1 for _, t in labels), default=1) * line_pt
        return [(lane * height, 0) for lane in flat]
    upright = lanes(lambda t: (t.count("\n") + 1) * line_pt + 2)
    longest = max((CHAR_EM * LABEL_PT * max(map(len, t.split("\n"))) for _, t in labels), default=0)
    return [(lane * (longest + 4), 90) for lane in upright]
