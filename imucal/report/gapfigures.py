"""The figures of the report's gap section, drawn from ``diagnosis.json`` in the words of
:mod:`imucal.report.gapwords` (figures are returned, never saved):

* :func:`plot_gap_map`: heat map of the scores, places (sensor, axis, part of the session) by
  statistic, both in plain words, in a colour-blind-safe map (``cividis`` of |z| on a log
  scale, the sign of a location in the gap printed in its cell);
* :func:`plot_effects`: the gap before and after adding each evaluated effect to the twin, in
  the order of the verdict (accepted effects in the order they were added, then the others).

Both are at most :data:`imucal.plots.style.PAGE_WIDTH_IN` wide with no text below
:data:`imucal.plots.style.MIN_FONT_PT`, so that they are legible where the report shows them.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np

from imucal.plots.style import MIN_FONT_PT, PAGE_WIDTH_IN
from imucal.report.gapwords import (
    effect_label,
    location_place,
    number,
    statistic_label,
    statistic_unit,
)

if TYPE_CHECKING:  # matplotlib is imported when a figure is drawn
    from matplotlib.figure import Figure

#: Font size of the map's tick labels (pt).
LABEL_PT = max(MIN_FONT_PT, 7.5)


def ordered_effects(diagnosis: Mapping) -> list[Mapping]:
    """The diagnosis's effects in the report's one order: the accepted ones in the order the
    diagnosis added them to the twin (``explained``), then the others as it ranked them."""
    order = {name: k for k, name in enumerate(diagnosis.get("explained", []))}
    effects = list(diagnosis.get("effects", []))
    first = sorted((e for e in effects if e["name"] in order), key=lambda e: order[e["name"]])
    return first + [e for e in effects if e["name"] not in order]


def _statistic_tick(name: str, sensors: set[str]) -> str:
    unit = statistic_unit(name, next(iter(sensors)) if len(sensors) == 1 else "")
    return f"{statistic_label(name)} ({unit})" if unit else statistic_label(name)


def plot_gap_map(diagnosis: Mapping) -> Figure:
    """Heat map of |z| per location: rows the places (sensor, axis, part of the session),
    columns the statistics, both in words."""
    from matplotlib.colors import LogNorm
    from matplotlib.figure import Figure

    locs = diagnosis["all_locations"]
    keys = sorted({(d["stage"], d["sensor"], d["axis"], d["segment"]) for d in locs})
    cols = sorted({d["statistic"] for d in locs}, key=statistic_label)
    z = np.full((len(keys), len(cols)), np.nan)
    flag = np.zeros(z.shape, dtype=bool)
    for d in locs:
        i = keys.index((d["stage"], d["sensor"], d["axis"], d["segment"]))
        j = cols.index(d["statistic"])
        z[i, j], flag[i, j] = d["z"], d["in_gap"]
    sensors = {c: {d["sensor"] for d in locs if d["statistic"] == c} for c in cols}
    places = [
        location_place(dict(zip(("stage", "sensor", "axis", "segment"), k, strict=True)))
        for k in keys
    ]
    # rows 0.22 in apart; the statistics' labels below the map take about 2.4 in
    fig = Figure(figsize=(PAGE_WIDTH_IN, max(4.5, 0.22 * len(keys) + 3.2)), layout="constrained")
    ax = fig.add_subplot()
    a = np.abs(z)
    top = max(10.0, float(np.nanmax(a))) if np.isfinite(a).any() else 10.0
    im = ax.imshow(np.where(np.isfinite(a), np.maximum(a, 0.1), np.nan), cmap="cividis",
                   norm=LogNorm(0.1, top), aspect="auto")  # fmt: skip
    for i, j in zip(*np.where(flag), strict=True):
        ax.text(j, i, "+" if z[i, j] > 0 else "−", ha="center", va="center", color="red",
                fontsize=10, fontweight="bold")  # fmt: skip
    ax.set_xticks(range(len(cols)), [_statistic_tick(c, sensors[c]) for c in cols],
                  rotation=60, ha="right", rotation_mode="anchor", fontsize=LABEL_PT)  # fmt: skip
    ax.set_yticks(range(len(keys)), places, fontsize=LABEL_PT)
    ax.set_xlabel("statistic (unit)")
    ax.set_ylabel("where")
    fig.colorbar(im, ax=ax, label="|z| against the twin's noise (+/−: in the gap)")
    ax.set_title(f"Gap map of {diagnosis['dataset']}")
    return fig


def _percent(x) -> str:
    """A share as a percentage as the report prints it, or 'n/a' when it is undefined (no gap
    to close)."""
    return "n/a" if x is None else f"{number(100 * x, 3)} %"


def plot_effects(diagnosis: Mapping) -> Figure:
    """Gap before and after each evaluated effect, in sample and held out (symlog scale), in
    the order of :func:`ordered_effects`."""
    from matplotlib.figure import Figure

    ev = [e for e in ordered_effects(diagnosis) if e["evaluated"]]
    fig = Figure(figsize=(PAGE_WIDTH_IN, 1.6 + 0.7 * max(len(ev), 1)), layout="constrained")
    ax = fig.add_subplot()
    if not ev:
        ax.text(0.5, 0.5, "no effect's estimate was outside the twin's noise", ha="center",
                va="center", transform=ax.transAxes)  # fmt: skip
        ax.set_axis_off()
        return fig
    y = np.arange(len(ev))
    ax.barh(y - 0.2, [e["gap_before"] for e in ev], 0.4, color="#999999", label="gap before")
    ax.barh(y + 0.2, [e["gap_after"] for e in ev], 0.4, color="#0072B2", label="gap after")
    ax.axvline(diagnosis["gap"]["null_p95"], color="#D55E00", ls="--",
               label="what noise alone stays below (95 %)")  # fmt: skip
    ax.set_xscale("symlog", linthresh=1.0)  # a gap closed entirely is 0
    ax.set_yticks(y, [f"{effect_label(e['name'])}\ncloses {_percent(e['shrink'])}, held out "
                      f"{_percent(e['heldout_shrink'])}{', accepted' if e['accepted'] else ''}"
                      for e in ev])  # fmt: skip
    ax.invert_yaxis()  # the first added on top
    ax.set_xlabel("gap: squared scores summed beyond what noise gives")
    ax.legend(fontsize=MIN_FONT_PT + 1, loc="lower left", bbox_to_anchor=(0, 1.0), ncol=3,
              frameon=False)  # fmt: skip
    return fig
