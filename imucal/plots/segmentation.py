"""Figure of one recording with its segments shaded and labelled."""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from imucal.columns import ACC, AXES, GYR, TIME

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
        Ingested recording (``t_s``, ``acc_*`` in m/s^2, ``gyr_*`` in rad/s).
    segments : DataFrame
        Segments table (``recording``, ``label``, ``kind``, ``start_s``, ``end_s``, ``turns``).
    recording : str, optional
        Plot only the segments of this recording; all rows when None.
    title : str
        Figure title (e.g. "dataset / recording").

    Returns
    -------
    matplotlib.figure.Figure
        Two panels sharing the time axis: gyro axes and norm in deg/s, accelerometer axes in
        m/s^2. Segments are shaded by kind and labelled at the top (phases and transitions with
        their raw turns).
    """
    missing = [c for c in (TIME, *ACC, *GYR) if c not in table.columns]
    if missing:
        raise ValueError(f"recording lacks column(s) {missing}; expected the ingested layout")
    if recording is not None:
        segments = segments[segments["recording"] == recording]
    t = table[TIME].to_numpy(dtype=float)
    gyr = np.degrees(table[list(GYR)].to_numpy(dtype=float))
    acc = table[list(ACC)].to_numpy(dtype=float)
    fig = Figure(figsize=(12, 6), layout="constrained")
    ax_g, ax_a = fig.subplots(2, 1, sharex=True)
    for k, axis in enumerate(AXES):
        ax_g.plot(t, gyr[:, k], lw=0.7, color=AXIS_COLOURS[axis], label=f"gyr {axis}")
        ax_a.plot(t, acc[:, k], lw=0.7, color=AXIS_COLOURS[axis], label=f"acc {axis}")
    ax_g.plot(t, np.linalg.norm(gyr, axis=1), lw=0.7, ls="--", color="#999999", label="|gyr|")
    seen = set()
    for row in segments.itertuples(index=False):
        colour = KIND_COLOURS.get(row.kind, "#999999")
        for ax in (ax_g, ax_a):
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
        ax_g.annotate(
            text,
            ((row.start_s + row.end_s) / 2, 1.0),
            xycoords=("data", "axes fraction"),
            ha="center",
            va="bottom",
            fontsize=7,
            rotation=90 if len(segments) > 14 else 0,
        )
    ax_g.set_ylabel("raw rate (deg/s)")
    ax_a.set_ylabel("raw specific force (m/s$^2$)")
    ax_a.set_xlabel("time (s)")
    for ax in (ax_g, ax_a):
        ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=7)
    if title:
        fig.suptitle(title)
    return fig
