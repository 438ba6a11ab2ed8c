"""Figure of the validation against an orientation reference (returns a Figure, never saves)."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from matplotlib.figure import Figure

from imucal.plots.style import PAGE_WIDTH_IN

#: Panels (recordings) per row.
PER_ROW = 3

#: Colours of the gyroscope variants.
_COLOURS = {"raw": "tab:red", "bias": "tab:orange", "calibrated": "tab:green"}


def plot_orientation_errors(validation: Mapping) -> Figure:
    """Median orientation error of the integrated gyroscope per window, per recording.

    Parameters
    ----------
    validation : mapping
        :func:`imucal.pipeline.reference.validate_references`.

    Returns
    -------
    Figure
        One panel per recording (held-out ones marked), bars per window and gyroscope
        (as read, bias only, calibrated), log scale in deg.
    """
    recordings = validation["recordings"]
    n = max(len(recordings), 1)
    cols = min(n, PER_ROW)
    rows = -(-n // cols)
    fig = Figure(figsize=(PAGE_WIDTH_IN, 3.3 * rows + 0.4), layout="constrained")
    axes = fig.subplots(rows, cols, squeeze=False).ravel()
    for ax in axes[n:]:
        ax.set_axis_off()
    for ax, (name, record) in zip(axes, recordings.items()):
        labels = [v for v in ("raw", "bias", "calibrated") if v in record]
        windows = list(record[labels[0]]["orientation"])
        width = 0.8 / len(labels)
        for k, label in enumerate(labels):
            values = [record[label]["orientation"][w]["median_deg"] for w in windows]
            values = [np.nan if v is None else v for v in values]
            ax.bar(np.arange(len(windows)) + k * width, values, width, label=label,
                   color=_COLOURS[label])  # fmt: skip
        ax.set_xticks(np.arange(len(windows)) + 0.4 - width / 2, windows)
        ax.set_yscale("log")
        ax.set_xlabel("window")
        ax.set_ylabel("median orientation error (°)")
        held = " (held out)" if record["held_out"] else " (fitted on)"
        ax.set_title(f"{name}{held}")
        ax.legend(fontsize="small")
    fig.suptitle("Gyroscope integrated over windows against the orientation reference")
    return fig
