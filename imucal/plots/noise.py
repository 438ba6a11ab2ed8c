"""Allan-deviation figure of the noise stage (log-log, confidence bars, fitted IEEE 952 terms)."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from matplotlib.figure import Figure

from imucal.noise.fit import term_adev
from imucal.plots.inertial import AXIS_COLOURS
from imucal.plots.style import PAGE_WIDTH_IN

_TERM_STYLE = {"Q": ":", "N": "--", "B": "-.", "K": (0, (1, 3)), "R": (0, (5, 5))}


def plot_allan(noise: Mapping) -> Figure:
    """One panel per analysed sensor: the Allan deviation of each axis with its confidence
    interval, the fitted model (solid) and the resolved terms of each axis (thin lines).

    Parameters
    ----------
    noise : mapping
        The ``noise.json`` content (:func:`imucal.noise.characterise_noise`).
    """
    sensors = noise["sensors"]
    # the sensors side by side across the page, two per row past two
    cols = min(len(sensors), 2)
    rows = -(-len(sensors) // cols)
    fig = Figure(figsize=(PAGE_WIDTH_IN, 3.9 * rows + 0.4), layout="constrained")
    axs = fig.subplots(rows, cols, squeeze=False).ravel()
    for ax in axs[len(sensors) :]:
        ax.set_axis_off()
    for ax, (sensor, data) in zip(axs, sensors.items()):
        for axis, fit in data["axes"].items():
            colour = AXIS_COLOURS[axis]
            tau, adev = np.array(fit["tau_s"]), np.array(fit["adev"])
            err = [adev - np.array(fit["ci_low"]), np.array(fit["ci_high"]) - adev]
            ax.errorbar(tau, adev, yerr=err, fmt="o", ms=3, color=colour, label=axis)
            ax.plot(tau, fit["model_adev"], color=colour, lw=1.2)
            for term, t in fit["terms"].items():
                if t["resolved"]:
                    ax.plot(tau, term_adev(term, t["value"], tau), color=colour, lw=0.7,
                            ls=_TERM_STYLE[term], alpha=0.7)  # fmt: skip
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("averaging time τ (s)")
        ax.set_ylabel(f"Allan deviation ({data['unit']})")
        ax.set_title(sensor)
        ax.grid(True, which="both", lw=0.3)
        ax.legend(fontsize=9, title="axis (lines: fit; thin: terms)", title_fontsize=9)
    fig.suptitle(
        f"{noise['recording']}: {noise['duration_s']:.0f} s at {noise['rate_hz']:.1f} Hz, "
        f"bars {100 * noise['level']:.0f} % confidence",
        fontsize=10,
    )
    return fig
