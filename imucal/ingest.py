"""Ingest of a raw log: checks of time and packet order, conversion to SI, summary.

A raw log has one row per received packet. Packets the radio lost leave a jump in the 16-bit
packet counter ``seq``; they are counted and reported, never invented (no row is added, no value
is filled in). The counter wraps at 65536, which is ambiguous in a long silence; the receiver
time ``t_s`` resolves it (:func:`resolve_packet_steps`).
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
from imucal.dataset import IMU_RECORDINGS, Dataset

#: Name of the recording that holds the MT Manager export of the reference IMU.
REFERENCE = "reference"
#: Steps up to this long (s) estimate the packet rate that resolves counter wraps in longer ones.
ORDINARY_STEP_S = 1.0
#: The summary lists at most this many gaps (all are counted).
MAX_LISTED_GAPS = 100
#: ``SampleTimeFine`` of the MT Manager export is an unsigned 32-bit tick counter.
REF_TICK_MODULUS = 2**32


# --------------------------------------------------------------------------------------------
# Packet counter


def resolve_packet_steps(
    seq: np.ndarray, t_s: np.ndarray, modulus: int = SEQ_MODULUS
) -> tuple[np.ndarray, float]:
    """Number of packets the counter advanced between consecutive rows, wraps resolved.

    Parameters
    ----------
    seq : ndarray, shape (n,)
        Packet counter, integers in ``[0, modulus)``.
    t_s : ndarray, shape (n,)
        Receiver time, s, non-decreasing.
    modulus : int
        The counter wraps at this value.

    Returns
    -------
    advance : ndarray, shape (n - 1,), int64
        Packets from row ``i`` to row ``i + 1``: 1 for consecutive packets, ``k + 1`` after
        ``k`` lost packets, 0 for a repeated counter (duplicated packet), negative for a counter
        that went back (out-of-order packet).
    rate_hz : float
        Packet rate estimated from the ordinary steps (forward by less than half the modulus,
        at most :data:`ORDINARY_STEP_S` long); NaN if the time does not advance in them.

    Notes
    -----
    The counter only gives the advance modulo ``modulus``: ``d = (seq[i+1] - seq[i]) mod M``.
    Of all ``d + k M`` (``k`` integer) the advance is the one nearest to the number of packets
    the elapsed time predicts, ``(t[i+1] - t[i]) * rate_hz``. In a step shorter than
    ``M / (2 rate)`` (327 s at 100 Hz) that is ``d`` or ``d - M``; only a longer silence can
    hide whole wraps, and the time counts them.
    """
    seq = np.asarray(seq, dtype=np.int64)
    t_s = np.asarray(t_s, dtype=float)
    d = np.mod(np.diff(seq), modulus)
    dt = np.diff(t_s)
    ordinary = (d >= 1) & (d < modulus // 2) & (dt <= ORDINARY_STEP_S)
    elapsed = dt[ordinary].sum()
    rate_hz = float(d[ordinary].sum() / elapsed) if elapsed > 0 else float("nan")
    # Only a step that went back or lasted long can differ from d (cheap on long logs); an
    # ordinary step keeps d for any packet rate below modulus / 2 / ORDINARY_STEP_S (32 kHz).
    advance = d.copy()
    odd = np.flatnonzero(~ordinary)
    expected = dt[odd] * rate_hz if np.isfinite(rate_hz) else np.zeros(odd.size)
    advance[odd] += np.round((expected - d[odd]) / modulus).astype(np.int64) * modulus
    return advance, rate_hz


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
        ticks = _unwrap(src[REF_TIME_FINE].to_numpy(dtype=np.int64), REF_TICK_MODULUS)
        t_s = ticks / REF_TICKS_PER_S
    else:
        t_s = _unwrap(counter, SEQ_MODULUS) / export.update_rate_hz
    data: dict[str, np.ndarray] = {TIME: t_s, SEQ: counter}
    for ours, theirs in ((ACC, REF_ACC), (GYR, REF_GYR), (MAG, REF_MAG)):
        for name, ref_name in zip(ours, theirs):
            data[name] = src[ref_name].to_numpy(dtype=float)
    used = {REF_COUNTER, REF_TIME_FINE, *REF_ACC, *REF_GYR, *REF_MAG}
    for name in src.columns:
        if name not in used:
            data[name] = src[name].to_numpy()
    return pd.DataFrame(data, copy=False)


def _unwrap(counter: np.ndarray, modulus: int) -> np.ndarray:
    """Counter continued across its wraps (assumes no step of half the modulus or more)."""
    steps = np.mod(np.diff(counter), modulus)
    steps = np.where(steps >= modulus // 2, steps - modulus, steps)
    return counter[0] + np.concatenate(([0], np.cumsum(steps)))


def ingest_recording(
    path: str | Path, recording: str, dataset: Dataset, imucal_version: str
) -> tuple[pd.DataFrame, dict]:
    """Read, check and convert one raw recording of a dataset.

    Parameters
    ----------
    path : str or Path
        The raw file: native IMU CSV, or the MT Manager export for ``recording='reference'``.
    recording : str
        Recording name ('rotation3d', 'cube', 'ratetable', 'static' or 'reference').
    dataset : Dataset
        Gives the sensitivities and the dataset name.
    imucal_version : str
        Package version, recorded in the metadata.

    Returns
    -------
    table : DataFrame, shape (n, 11 + extra)
        The ingested recording (``docs/architecture.md``).
    metadata : dict
        ``dataset``, ``recording``, ``source``, ``format``, ``sha256``, ``sensitivity``
        (None for the reference, which is in SI units already), ``units`` (per column),
        ``first_line`` (line of row 0 in the source), ``extra_columns``, ``imucal_version``,
        and for the reference ``update_rate_hz`` and ``header``.

    Raises
    ------
    ValueError
        If ``recording`` is not a known name.
    FileNotFoundError, RawDataError
        From the reader and :func:`check_log`.
    """
    metadata: dict[str, Any] = {
        "dataset": dataset.name,
        "recording": recording,
        "source": str(path),
        "imucal_version": imucal_version,
    }
    if recording == REFERENCE:
        export = io.read_mt_manager_export(path)
        table = reference_to_table(export)
        first_line = export.first_line
        metadata.update(
            format=io.MT_MANAGER_FORMAT,
            sensitivity=None,
            update_rate_hz=export.update_rate_hz,
            header=export.header,
        )
    elif recording in IMU_RECORDINGS:
        counts = io.read_imu_csv(path)
        first_line = 2
        table = counts_to_si(counts, dataset.sensitivity)
        metadata.update(format=io.IMU_CSV_FORMAT, sensitivity=dict(dataset.sensitivity))
    else:
        raise ValueError(
            f"unknown recording {recording!r}; expected one of {(*IMU_RECORDINGS, REFERENCE)}"
        )
    check_log(table, path, first_line)
    extra = [c for c in table.columns if c not in RAW_COLUMNS]
    units = {TIME: "s", SEQ: "1"}
    units.update({c: SI_UNITS[s] for s, cols in SENSOR_COLUMNS.items() for c in cols})
    units.update({c: "as in the source" for c in extra})
    metadata.update(
        sha256=io.sha256_file(path), units=units, first_line=first_line, extra_columns=extra
    )
    return table, metadata


# --------------------------------------------------------------------------------------------
# Summary


def summarize_recording(table: pd.DataFrame, metadata: Mapping[str, Any]) -> dict:
    """Summarise an ingested recording: duration, rates, lost packets, gaps, order, mag samples.

    Parameters
    ----------
    table : DataFrame, shape (n, k)
        Ingested recording (``t_s`` in s, ``seq``, ``mag_*`` NaN where no fresh sample).
    metadata : mapping
        Its metadata (``source``, ``format``, ``sha256``, ``first_line``, ``extra_columns``).

    Returns
    -------
    dict
        ``rows``, ``t_start_s``, ``t_end_s``, ``duration_s``, ``rate_hz`` (packet rate,
        lost packets included), ``received_rate_hz``, ``lost_packets`` (from ``seq`` across
        wraps), ``lost_fraction``, ``n_gaps``, ``gaps`` (the first :data:`MAX_LISTED_GAPS`:
        ``line``, ``t_s``, ``dt_s``, ``seq_before``, ``seq``, ``lost``), ``duplicated_rows``,
        ``out_of_order_rows``, ``mag_samples``, ``mag_rate_hz`` (received magnetometer
        samples per second), ``extra_columns`` and the source's ``source``, ``format``,
        ``sha256``. Unknown values are None, never NaN.

    Notes
    -----
    Packets lost before the first or after the last received row leave no jump in ``seq``
    and cannot be counted.
    """
    t_s = table[TIME].to_numpy(dtype=float)
    seq = table[SEQ].to_numpy(dtype=np.int64)
    first_line = int(metadata.get("first_line", 2))
    n = len(t_s)
    duration = float(t_s[-1] - t_s[0]) if n else 0.0
    advance, _ = resolve_packet_steps(seq, t_s)
    forward = advance[advance > 0]
    lost = np.where(advance > 1, advance - 1, 0)
    gap_steps = np.flatnonzero(advance > 1)
    gaps = [
        {
            "line": int(first_line + i + 1),
            "t_s": float(t_s[i + 1]),
            "dt_s": float(t_s[i + 1] - t_s[i]),
            "seq_before": int(seq[i]),
            "seq": int(seq[i + 1]),
            "lost": int(lost[i]),
        }
        for i in gap_steps[:MAX_LISTED_GAPS]
    ]
    has_mag = ~np.isnan(table[MAG[0]].to_numpy(dtype=float))
    t_mag = t_s[has_mag]
    mag_span = float(t_mag[-1] - t_mag[0]) if t_mag.size >= 2 else 0.0
    lost_total = int(lost.sum())
    return {
        "source": metadata.get("source"),
        "format": metadata.get("format"),
        "sha256": metadata.get("sha256"),
        "rows": n,
        "t_start_s": float(t_s[0]) if n else None,
        "t_end_s": float(t_s[-1]) if n else None,
        "duration_s": duration,
        "rate_hz": float(forward.sum()) / duration if duration > 0 else None,
        "received_rate_hz": (n - 1) / duration if duration > 0 else None,
        "lost_packets": lost_total,
        "lost_fraction": lost_total / (n + lost_total) if n else None,
        "n_gaps": int(gap_steps.size),
        "gaps": gaps,
        "duplicated_rows": int(np.count_nonzero(advance == 0)),
        "out_of_order_rows": int(np.count_nonzero(advance < 0)),
        "mag_samples": int(has_mag.sum()),
        "mag_rate_hz": (t_mag.size - 1) / mag_span if mag_span > 0 else None,
        "extra_columns": list(metadata.get("extra_columns", [])),
    }


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
        ``lost_packets``.
    """
    per_recording = {name: summarize_recording(t, m) for name, (t, m) in recordings.items()}
    return {
        "dataset": dataset,
        "lost_packets": sum(s["lost_packets"] for s in per_recording.values()),
        "recordings": per_recording,
    }
