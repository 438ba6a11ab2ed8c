"""Ingest of a raw log: checks of time and packet order, conversion to SI, summary.

A raw log has one row per received packet. Packets the radio lost leave a jump in the 16-bit
packet counter ``seq``; they are counted and reported, never invented (no row is added, no value
is filled in). The counter wraps at 65536, which is ambiguous in a long silence; the receiver
time ``t_s`` resolves it (:func:`resolve_packet_steps`).

The module (about 520 lines) holds ingestion end to end, checks, conversion and the summary,
because the summary reports exactly what the checks found.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from imucal import io
from imucal.columns import (
    ACC,
    GYR,
    MAG,
    RAW_COLUMNS,
    REF_ACC,
    REF_COUNTER,
    REF_GYR,
    REF_MAG,
    REF_TICKS_PER_S,
    REF_TIME_FINE,
    SENSOR_COLUMNS,
    SEQ,
    SEQ_MODULUS,
    SI_UNITS,
    TIME,
)
from imucal.constants import REFERENCE
from imucal.ingest.timebase import describe_timestamps, resolve_packet_steps, unwrap_counter
from imucal.io import readers
from imucal.io.dataset import Dataset

__all__ = [
    "check_log",
    "counts_to_si",
    "ingest_recording",
    "reference_to_table",
    "resolve_packet_steps",
    "summarize_dataset",
    "summarize_recording",
    "unwrap_counter",
]

#: The summary lists at most this many gaps (all are counted).
MAX_LISTED_GAPS = 100
#: ``SampleTimeFine`` of the MT Manager export is an unsigned 32-bit tick counter.
REF_TICK_MODULUS = 2**32


# --------------------------------------------------------------------------------------------
# Checks


def check_log(table: pd.DataFrame, source: str | Path, first_line: int) -> None:
    """Refuse a log whose time or packet order breaks the contract.

    Parameters
    ----------
    table : DataFrame, shape (n, k)
        With ``t_s`` (s) and ``seq`` columns, one row per packet as read from the file.
    source : str or Path
        File name for the messages.
    first_line : int
        Line number of row 0 in ``source`` (row ``i`` is on line ``first_line + i``).

    Raises
    ------
    RawDataError
        Fewer than two rows, ``t_s`` not finite, going backwards or not advancing at all,
        ``seq`` outside ``[0, 65535]``, a duplicated ``seq`` (same counter as the row before)
        or an out-of-order ``seq``. The message names the first offending line.
    """
    t_s = table[TIME].to_numpy(dtype=float)
    seq = table[SEQ].to_numpy()
    n = len(t_s)
    if n < 2:
        raise io.RawDataError(source, first_line, f"{n} data row", "at least two rows")
    bad = np.flatnonzero(~np.isfinite(t_s))
    if bad.size:
        raise io.RawDataError(
            source,
            first_line + bad[0],
            f"t_s is {float(t_s[bad[0]])}",
            "a finite receiver time in s",
        )
    back = np.flatnonzero(np.diff(t_s) < 0)
    if back.size:
        i = back[0] + 1
        raise io.RawDataError(
            source,
            first_line + i,
            f"t_s {float(t_s[i])!r} s is earlier than {float(t_s[i - 1])!r} s "
            f"on line {first_line + i - 1}",
            "non-decreasing receiver time t_s",
        )
    if t_s[-1] == t_s[0]:
        raise io.RawDataError(
            source,
            None,
            f"t_s stays at {float(t_s[0])!r} s on all {n} rows",
            "a receiver time that advances",
        )
    bad = np.flatnonzero((seq < 0) | (seq >= SEQ_MODULUS))
    if bad.size:
        raise io.RawDataError(
            source,
            first_line + bad[0],
            f"seq {seq[bad[0]]}",
            f"a 16-bit packet counter in 0..{SEQ_MODULUS - 1}",
        )
    advance, _ = resolve_packet_steps(seq, t_s)
    bad = np.flatnonzero(advance <= 0)
    if bad.size:
        i = bad[0] + 1
        if advance[bad[0]] == 0:
            found = f"seq {seq[i]} repeats the seq of line {first_line + i - 1} (duplicated packet)"
        else:
            found = (
                f"seq {seq[i]} goes back from {seq[i - 1]} on line {first_line + i - 1} "
                "(out-of-order packet)"
            )
        raise io.RawDataError(
            source,
            first_line + i,
            found,
            "each packet once, in order (seq increasing modulo 65536)",
        )


# --------------------------------------------------------------------------------------------
# Conversion to the ingested table


def counts_to_si(counts: pd.DataFrame, sensitivity: Mapping[str, float]) -> pd.DataFrame:
    """Convert raw counts to SI units: ``reading = counts * sensitivity``.

    Parameters
    ----------
    counts : DataFrame, shape (n, 11 + extra)
        As from :func:`imucal.io.read_imu_csv` (counts; ``mag_*`` NaN where no fresh sample).
    sensitivity : mapping
        SI unit per count for 'acc' (m/s^2), 'gyr' (rad/s), 'mag' (normalised field).

    Returns
    -------
    DataFrame, shape (n, 11 + extra)
        ``t_s`` (float64, s), ``seq`` (int64), sensors in float64 SI units (NaN kept, never
        filled), extra columns unchanged, in that order.

    Raises
    ------
    ValueError
        If a sensitivity is missing, not finite or not positive.
    """
    data: dict[str, np.ndarray] = {
        TIME: counts[TIME].to_numpy(dtype=float),
        SEQ: counts[SEQ].to_numpy(dtype=np.int64),
    }
    for sensor, columns in SENSOR_COLUMNS.items():
        factor = sensitivity.get(sensor)
        if factor is None or not np.isfinite(factor) or factor <= 0:
            raise ValueError(
                f"sensitivity of {sensor!r} is {factor!r}; expected a positive "
                f"number of {SI_UNITS[sensor]} per count"
            )
        for name in columns:
            values = np.array(counts[name], dtype=float)  # a copy: scaled in place below
            values *= float(factor)
            data[name] = values
    for name in counts.columns:
        if name not in RAW_COLUMNS:
            data[name] = counts[name].to_numpy()
    return pd.DataFrame(data, copy=False)


def reference_to_table(export: io.MtManagerExport) -> pd.DataFrame:
    """Rename the reference's columns to the ingested names (its own axes, SI units already).

    Parameters
    ----------
    export : MtManagerExport
        As from :func:`imucal.io.read_mt_manager_export`.

    Returns
    -------
    DataFrame, shape (n, 11 + extra)
        ``t_s`` (s, the reference's own clock): ``SampleTimeFine / 10000`` unwrapped at 2^32
        ticks, or, without it, ``PacketCounter`` unwrapped at 65536 divided by the update
        rate; ``seq`` = ``PacketCounter``; ``acc_*`` (m/s^2), ``gyr_*`` (rad/s), ``mag_*``
        (normalised) copied; other exported columns unchanged.
    """
    src = export.table
    counter = src[REF_COUNTER].to_numpy(dtype=np.int64)
    if REF_TIME_FINE in src.columns:
        ticks = unwrap_counter(src[REF_TIME_FINE].to_numpy(dtype=np.int64), REF_TICK_MODULUS)
        t_s = ticks / REF_TICKS_PER_S
    else:
        t_s = unwrap_counter(counter, SEQ_MODULUS) / export.update_rate_hz
    data: dict[str, np.ndarray] = {TIME: t_s, SEQ: counter}
    for ours, theirs in ((ACC, REF_ACC), (GYR, REF_GYR), (MAG, REF_MAG)):
        for name, ref_name in zip(ours, theirs):
            data[name] = src[ref_name].to_numpy(dtype=float)
    used = {REF_COUNTER, REF_TIME_FINE, *REF_ACC, *REF_GYR, *REF_MAG}
    for name in src.columns:
        if name not in used:
            data[name] = src[name].to_numpy()
    return pd.DataFrame(data, copy=False)


def ingest_recording(
    path: str | Path, recording: str, dataset: Dataset, imucal_version: str
) -> tuple[pd.DataFrame, dict]:
    """Read, check and convert one raw recording of a dataset.

    Parameters
    ----------
    path : str or Path
        The raw file: native IMU CSV, the MT Manager export for ``recording='reference'``, or
        for a recording declared with a reader its first file (``dataset.recordings[name]``;
        the declaration names the others).
    recording : str
        Recording name (one of :data:`imucal.io.dataset.RECORDING_NAMES`).
    dataset : Dataset
        Gives the sensitivities, the reader declarations, the section list and the name.
    imucal_version : str
        Package version, recorded in the metadata.

    Returns
    -------
    table : DataFrame, shape (n, k)
        The ingested recording (``docs/data-format.md``).
    metadata : dict
        ``dataset``, ``recording``, ``source``, ``format``, ``sha256``, ``sensitivity``
        (None for the reference, which is in SI units already), ``units`` (per column),
        ``sensors`` (present), ``has_seq``, ``first_line`` (line of row 0 in the source, None
        when rows are not lines of one file), ``extra_columns``, ``imucal_version``; for the
        reference ``update_rate_hz`` and ``header``; for a declared recording ``reader``,
        ``files`` (path and sha256 of each), ``source_units``, ``streams``/``parts`` and
        ``sections`` (manual segment entries from the section list, when it names this
        recording).

    Raises
    ------
    ValueError
        If ``recording`` is not a recording of the dataset, or ``path`` is not its file.
    FileNotFoundError, RawDataError, DeclarationError
        From the readers and :func:`check_log`.
    """
    if recording not in dataset.recordings:
        raise ValueError(
            f"unknown recording {recording!r}; dataset {dataset.name!r} has "
            f"{sorted(dataset.recordings)}"
        )
    metadata: dict[str, Any] = {
        "dataset": dataset.name,
        "recording": recording,
        "source": str(path),
        "imucal_version": imucal_version,
    }
    if recording in dataset.readers:
        if Path(path).resolve() != Path(dataset.recordings[recording]).resolve():
            raise ValueError(
                f"{path}: not the file of the declared recording {recording!r}; expected "
                f"{dataset.recordings[recording]}"
            )
        table, declared = _ingest_declared(recording, dataset)
        metadata.update(declared)
    elif recording == REFERENCE:
        export = io.read_mt_manager_export(path)
        table = reference_to_table(export)
        check_log(table, path, export.first_line)
        metadata.update(
            format=io.MT_MANAGER_FORMAT,
            sensitivity=None,
            update_rate_hz=export.update_rate_hz,
            header=export.header,
            first_line=export.first_line,
            sha256=io.sha256_file(path),
        )
    else:
        counts = io.read_imu_csv(path)
        table = counts_to_si(counts, dataset.sensitivity)
        check_log(table, path, 2)
        metadata.update(
            format=io.IMU_CSV_FORMAT,
            sensitivity=dict(dataset.sensitivity),
            first_line=2,
            sha256=io.sha256_file(path),
        )
    sensors = [s for s, cols in SENSOR_COLUMNS.items() if cols[0] in table.columns]
    extra = [c for c in table.columns if c not in (TIME, SEQ) and c not in _SENSOR_COLUMN_NAMES]
    units = {TIME: "s"}
    if SEQ in table.columns:
        units[SEQ] = "1"
    units.update({c: SI_UNITS[s] for s in sensors for c in SENSOR_COLUMNS[s]})
    units.update({c: "as in the source" for c in extra})
    metadata.update(units=units, sensors=sensors, has_seq=SEQ in table.columns, extra_columns=extra)
    return table, metadata


_SENSOR_COLUMN_NAMES = {c for cols in SENSOR_COLUMNS.values() for c in cols}


def _ingest_declared(recording: str, dataset: Dataset) -> tuple[pd.DataFrame, dict]:
    """A recording declared with a reader: read, check, resolve its section list."""
    where = f"{dataset.yaml_path}: recordings.{recording}"
    sections = dataset.sections if (dataset.sections or {}).get("recording") == recording else None
    label_column = sections.get("from_column") if sections else None
    rec = readers.read_declared(
        dataset.readers[recording],
        where=where,
        field_norm_t=dataset.field_norm_t,
        label_column=label_column,
    )
    table = rec.table
    first_line = rec.metadata.get("first_line")
    files = rec.metadata["files"]
    if SEQ in table.columns:
        check_log(table, files[0]["path"] if len(files) == 1 else where, first_line or 0)
    meta: dict[str, Any] = {
        "format": "declared",
        "reader": dataset.readers[recording],
        "files": files,
        "sha256": files[0]["sha256"],
        "source_units": rec.metadata["source_units"],
        "sensitivity": _declared_sensitivity(dataset.readers[recording]),
        "first_line": first_line if len(files) == 1 else None,
        "field_norm_t": dataset.field_norm_t,
    }
    for key in ("streams", "parts", "part_gap_s", "sorted_by_time"):
        if key in rec.metadata:
            meta[key] = rec.metadata[key]
    if sections is not None:
        meta["sections"] = readers.read_sections(
            sections,
            where=f"{dataset.yaml_path}: sections",
            t_s=table[TIME].to_numpy(dtype=float),
            primary_t_s=rec.primary_t_s,
            labels=rec.labels,
        )
        if "file" in sections:
            meta["sections_file"] = {
                "path": sections["file"],
                "sha256": io.sha256_file(sections["file"]),
            }
    return table, meta


def _declared_sensitivity(declaration: Mapping[str, Any]) -> dict:
    """Sensitivities (SI per count) of the entries of a declaration, by sensor."""
    entries = [declaration]
    out: dict = {}
    while entries:
        entry = entries.pop(0)
        entries += list(entry.get("parts", [])) + list(entry.get("streams", []))
        out.update(entry.get("sensitivity") or {})
    return out


# --------------------------------------------------------------------------------------------
# Summary


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
        ``source_units``, ``parts``. Unknown values are None, never NaN.

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
    summary.update(
        sensors=sensors,
        samples=samples,
        sample_rate_hz=sample_rate,
        mag_samples=samples.get("mag", 0),
        mag_rate_hz=sample_rate.get("mag"),
        extra_columns=list(metadata.get("extra_columns", [])),
        notes=notes,
    )
    for key in ("files", "source_units", "parts", "sections"):
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
