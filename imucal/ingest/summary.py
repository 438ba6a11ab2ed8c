"""Summary of ingested recordings: duration, rates, time steps, lost packets, sensors.

Packets lost between received rows are counted from the packet counter ``seq`` across its
wraps (:func:`imucal.ingest.timebase.resolve_packet_steps`); the summary reports what the
ingest's checks let through, it adds or fills nothing.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd

from imucal.columns import SENSOR_COLUMNS, SEQ, TIME
from imucal.ingest.timebase import describe_timestamps, resolve_packet_steps

__all__ = ["MAX_LISTED_GAPS", "summarize_dataset", "summarize_recording"]

#: The summary lists at most this many gaps (all are counted).
MAX_LISTED_GAPS = 100


def summarize_recording(table: pd.DataFrame, metadata: Mapping[str, Any]) -> dict:
    """Summarise an ingested recording: duration, rates, time steps, lost packets, sensors.

    Parameters
    ----------
    table : DataFrame, shape (n, k)
        Ingested recording (``t_s`` in s, ``seq`` when there is a counter, the columns of the
        sensors present, NaN on rows without a sample of that sensor).
    metadata : mapping
        Its metadata (``source``, ``format``, ``sha256``, ``first_line``, ``extra_columns``, and
        for a declared recording ``files``, ``source_units``, ``parts``).

    Returns
    -------
    dict
        ``rows``, ``t_start_s``, ``t_end_s``, ``duration_s``, ``rate_hz`` (packet rate,
        lost packets included; without a counter the received rate), ``received_rate_hz``,
        the time-step statistics of :func:`imucal.ingest.timebase.describe_timestamps`
        (``dt_median_s``, ``dt_mean_s``, ``dt_max_s``, ``effective_rate_hz`` = rows /
        duration, ``non_increasing_steps``, ``irregular``, ``nominal_period_s``),
        ``has_seq``, ``lost_packets`` (from ``seq`` across wraps; None without a counter),
        ``lost_fraction``, ``n_gaps``, ``gaps`` (the first :data:`MAX_LISTED_GAPS`: ``line``,
        ``t_s``, ``dt_s``, ``seq_before``, ``seq``, ``lost``), ``duplicated_rows``,
        ``out_of_order_rows``, ``sensors`` (present), ``samples`` and ``sample_rate_hz`` per
        sensor, ``mag_samples``, ``mag_rate_hz``, ``notes`` (what could not be checked),
        ``extra_columns`` and the source's ``source``, ``format``, ``sha256``, ``files``,
        ``source_units``, ``parts``, ``clipped`` (per sensor read in raw counts, the samples
        at a limit of its range). Unknown values are None, never NaN.

    Notes
    -----
    Packets lost before the first or after the last received row leave no jump in ``seq``
    and cannot be counted; without ``seq`` no lost packet can be counted at all.
    """
    t_s = table[TIME].to_numpy(dtype=float)
    first_line = metadata.get("first_line")
    n = len(t_s)
    duration = float(t_s[-1] - t_s[0]) if n else 0.0
    has_seq = SEQ in table.columns
    notes = []
    summary: dict[str, Any] = {
        "source": metadata.get("source"),
        "format": metadata.get("format"),
        "sha256": metadata.get("sha256"),
        "rows": n,
        "t_start_s": float(t_s[0]) if n else None,
        "t_end_s": float(t_s[-1]) if n else None,
        "duration_s": duration,
        "received_rate_hz": (n - 1) / duration if duration > 0 else None,
        **describe_timestamps(t_s),
        "has_seq": has_seq,
    }
    if has_seq:
        seq = table[SEQ].to_numpy(dtype=np.int64)
        advance, _ = resolve_packet_steps(seq, t_s)
        forward = advance[advance > 0]
        lost = np.where(advance > 1, advance - 1, 0)
        gap_steps = np.flatnonzero(advance > 1)
        line0 = 0 if first_line is None else int(first_line)
        gaps = [
            {
                "line": int(line0 + i + 1) if first_line is not None else None,
                "t_s": float(t_s[i + 1]),
                "dt_s": float(t_s[i + 1] - t_s[i]),
                "seq_before": int(seq[i]),
                "seq": int(seq[i + 1]),
                "lost": int(lost[i]),
            }
            for i in gap_steps[:MAX_LISTED_GAPS]
        ]
        lost_total = int(lost.sum())
        summary.update(
            rate_hz=float(forward.sum()) / duration if duration > 0 else None,
            lost_packets=lost_total,
            lost_fraction=lost_total / (n + lost_total) if n else None,
            n_gaps=int(gap_steps.size),
            gaps=gaps,
            duplicated_rows=int(np.count_nonzero(advance == 0)),
            out_of_order_rows=int(np.count_nonzero(advance < 0)),
        )
    else:
        notes.append("no packet counter (seq): lost packets cannot be counted")
        summary.update(
            rate_hz=summary["received_rate_hz"],
            lost_packets=None,
            lost_fraction=None,
            n_gaps=None,
            gaps=[],
            duplicated_rows=None,
            out_of_order_rows=None,
        )
    if summary["irregular"]:
        notes.append(
            "irregular timestamps (receive times in bursts): kept as they are; the nominal "
            "period is the effective one"
        )
    sensors = [s for s, cols in SENSOR_COLUMNS.items() if cols[0] in table.columns]
    absent = [s for s in SENSOR_COLUMNS if s not in sensors]
    if absent:
        notes.append(f"sensors absent from this recording: {', '.join(absent)}")
    samples: dict[str, int] = {}
    sample_rate: dict[str, float | None] = {}
    for sensor in sensors:
        has = ~np.isnan(table[SENSOR_COLUMNS[sensor][0]].to_numpy(dtype=float))
        t_own = t_s[has]
        span = float(t_own[-1] - t_own[0]) if t_own.size >= 2 else 0.0
        samples[sensor] = int(has.sum())
        sample_rate[sensor] = (t_own.size - 1) / span if span > 0 else None
    clipped = {k: v for k, v in (metadata.get("clipped") or {}).items() if v}
    if clipped:
        notes.append(
            "samples with a reading at a limit of the sensor's range (clipped, kept): "
            + ", ".join(f"{sensor} {rows}" for sensor, rows in clipped.items())
        )
    summary.update(
        sensors=sensors,
        samples=samples,
        sample_rate_hz=sample_rate,
        mag_samples=samples.get("mag", 0),
        mag_rate_hz=sample_rate.get("mag"),
        extra_columns=list(metadata.get("extra_columns", [])),
        notes=notes,
    )
    for key in ("files", "source_units", "parts", "sections", "clipped"):
        if key in metadata:
            summary[key] = metadata[key]
    return summary


def summarize_dataset(
    recordings: Mapping[str, tuple[pd.DataFrame, Mapping[str, Any]]], dataset: str
) -> dict:
    """Summary of all ingested recordings of a dataset (the ``summary.json`` of the ingest).

    Parameters
    ----------
    recordings : mapping
        Recording name -> (ingested table, metadata), as from :func:`imucal.io.read_recording`.
    dataset : str
        Dataset name.

    Returns
    -------
    dict
        ``{'dataset': ..., 'recordings': {name: summarize_recording(...)}}`` plus the total
        ``lost_packets`` of the recordings with a packet counter and ``sensors`` (present in
        some recording).
    """
    per_recording = {name: summarize_recording(t, m) for name, (t, m) in recordings.items()}
    return {
        "dataset": dataset,
        "lost_packets": sum(s["lost_packets"] or 0 for s in per_recording.values()),
        "sensors": [
            s for s in SENSOR_COLUMNS if any(s in r["sensors"] for r in per_recording.values())
        ],
        "recordings": per_recording,
    }
