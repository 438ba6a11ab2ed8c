"""Saturation seen in the readings themselves: a diagnosis that cannot replay a session's
motion still names clipped samples.

A reading at a limit of its sensor's range is a clipped sample (the input exceeded the range).
That is evidence in the data, whether or not a twin can replicate the phase it occurred in.
A sensor clips where the declared range says (``range_counts`` x ``sensitivity``), and also
where no range is declared or the part's range is smaller than the declared one: its readings
then pile up at one extreme value (:func:`pile_up_rows`), far more often than at the values
just inside it. The full protocol's statistic ``clip_fraction`` counts both
(:func:`imucal.gap.locations.clip_fractions`); a partial session's diagnosis reads the raw
counts at a limit that the ingest counted per recording (:func:`ingest_clip_fractions`, the
``clipped`` entries of ``summary.json``). Either way the diagnosis then notes ``saturation``
with the fraction per sensor (:func:`note_saturation`).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

__all__ = ["PILE_UP_RATIO", "ingest_clip_fractions", "note_saturation", "pile_up_rows"]

#: A value is a pile-up when it is the extreme of its axis (either sign), held by at least
#: :data:`PILE_UP_MIN` samples and by more than this many times the mean count of the
#: :data:`PILE_UP_NEIGHBOURS` distinct values next to it inside the range (plus one).
PILE_UP_RATIO = 10.0
PILE_UP_MIN = 5
PILE_UP_NEIGHBOURS = 5


def pile_up_rows(values: np.ndarray) -> np.ndarray:
    """The rows whose reading sits at a pile-up of identical extreme values on some axis.

    A sensor whose input exceeds its range outputs the range's limit, again and again: its
    histogram has a spike at the extreme value, while a signal that merely reaches far has
    few samples there, no more than at the values just inside it. Exact equality is what a
    clipped reading keeps (the same count, and the same SI value made from it); the test needs
    no declared range and no unit.

    Parameters
    ----------
    values : ndarray, shape (n, k)
        Readings (any unit), NaN where a row has none.

    Returns
    -------
    ndarray of bool, shape (n,)
        True where a reading of the row equals an axis's piled-up extreme.
    """
    x = np.asarray(values, dtype=float)
    rows = np.zeros(len(x), dtype=bool)
    for j in range(x.shape[1]):
        col = x[:, j]
        ok = np.isfinite(col)
        if ok.sum() < PILE_UP_MIN:
            continue
        levels, counts = np.unique(col[ok], return_counts=True)
        for edge, inside in ((-1, slice(-1 - PILE_UP_NEIGHBOURS, -1)),
                             (0, slice(1, 1 + PILE_UP_NEIGHBOURS))):  # fmt: skip
            near = counts[inside]
            if counts[edge] >= PILE_UP_MIN and counts[edge] > PILE_UP_RATIO * (
                (near.mean() if len(near) else 0.0) + 1.0
            ):
                rows |= col == levels[edge]
    return rows


def ingest_clip_fractions(summary: Mapping) -> dict[str, float]:
    """Per sensor, the fraction of its samples at a limit of its range, from the ingest.

    Parameters
    ----------
    summary : mapping
        The ingest's ``summary.json`` (:func:`imucal.ingest.summary.summarize_dataset`).

    Returns
    -------
    dict of str to float
        Sensor -> clipped samples / samples, over the recordings that read it in raw counts
        (those with a ``clipped`` count for it); sensors no recording reads in counts are
        absent.
    """
    clipped: dict[str, int] = {}
    samples: dict[str, int] = {}
    for recording in summary["recordings"].values():
        for sensor, rows in (recording.get("clipped") or {}).items():
            clipped[sensor] = clipped.get(sensor, 0) + int(rows)
            samples[sensor] = samples.get(sensor, 0) + int(recording["samples"].get(sensor, 0))
    return {s: clipped[s] / samples[s] for s in clipped if samples[s]}


def note_saturation(result: dict, fractions: Mapping[str, float]) -> dict:
    """``result`` (a diagnosis) with ``saturation`` noted where a sensor's readings clip.

    Parameters
    ----------
    result : dict
        A diagnosis.json content; changed in place.
    fractions : mapping of str to float
        Sensor -> fraction of its samples at its range.

    Returns
    -------
    dict
        ``result``; when a fraction is positive: ``saturation`` joins ``noted``,
        ``saturation: {'clip_fraction': {sensor: fraction}}`` gives the evidence, and
        saturation leaves ``not_observable`` (its evidence is in the readings, whatever the
        scope can replay).
    """
    clipped = {s: float(f) for s, f in fractions.items() if f > 0}
    if clipped:
        result["noted"] = [
            *(n for n in result.get("noted") or [] if n != "saturation"),
            "saturation",
        ]
        result["saturation"] = {"clip_fraction": clipped}
        result.get("not_observable", {}).pop("saturation", None)
    return result
