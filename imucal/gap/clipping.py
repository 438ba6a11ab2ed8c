"""Saturation seen in the readings themselves: a diagnosis that cannot replay a session's
motion still names clipped samples.

A reading at a limit of its sensor's range is a clipped sample (the input exceeded the range).
That is evidence in the data, whether or not a twin can replicate the phase it occurred in:
the full protocol's fallback counts the readings within 1.5 LSB of ``range_counts`` x
``sensitivity`` (:func:`imucal.gap.locations.clip_fractions`), and a partial session's
diagnosis reads the raw counts at a limit that the ingest counted per recording
(:func:`ingest_clip_fractions`, the ``clipped`` entries of ``summary.json``). Either way the
diagnosis then notes ``saturation`` with the fraction per sensor (:func:`note_saturation`).
Recordings read in SI units have no known range: their clipping cannot be counted.
"""

from __future__ import annotations

from collections.abc import Mapping

__all__ = ["ingest_clip_fractions", "note_saturation"]


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
