"""Ingest of a raw log: read, check (:mod:`imucal.ingest.checks`) and convert to SI units.

A raw log has one row per received packet. Packets the radio lost leave a jump in the 16-bit
packet counter ``seq``; they are counted and reported, never invented (no row is added, no value
is filled in). A native CSV is ingested in batches of bounded memory (:func:`ingest_to_parquet`);
the summary of an ingested table is in :mod:`imucal.ingest.summary`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc

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
from imucal.ingest.checks import CountRange, LogChecks, check_count_range, check_log
from imucal.ingest.timebase import unwrap_counter
from imucal.io import readers
from imucal.io.dataset import Dataset

__all__ = [
    "check_log",
    "counts_to_si",
    "ingest_recording",
    "ingest_to_parquet",
    "reference_to_table",
    "unwrap_counter",
]

#: ``SampleTimeFine`` of the MT Manager export is an unsigned 32-bit tick counter.
REF_TICK_MODULUS = 2**32


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
    factors = _factors(sensitivity)
    data: dict[str, np.ndarray] = {
        TIME: counts[TIME].to_numpy(dtype=float),
        SEQ: counts[SEQ].to_numpy(dtype=np.int64),
    }
    for sensor, columns in SENSOR_COLUMNS.items():
        for name in columns:
            values = np.array(counts[name], dtype=float)  # a copy: scaled in place below
            values *= factors[sensor]
            data[name] = values
    for name in counts.columns:
        if name not in RAW_COLUMNS:
            data[name] = counts[name].to_numpy()
    return pd.DataFrame(data, copy=False)


def _factors(sensitivity: Mapping[str, float]) -> dict[str, float]:
    """SI unit per count by sensor, checked (see :func:`counts_to_si`)."""
    out = {}
    for sensor in SENSOR_COLUMNS:
        factor = sensitivity.get(sensor)
        if factor is None or not np.isfinite(factor) or factor <= 0:
            raise ValueError(
                f"sensitivity of {sensor!r} is {factor!r}; expected a positive "
                f"number of {SI_UNITS[sensor]} per count"
            )
        out[sensor] = float(factor)
    return out


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
        recording); ``clipped``: per sensor read in raw counts (a native CSV, or declared in
        ``counts``), the samples with a reading at a limit of ``range_counts`` on any axis
        (sensors read in SI units are absent: their range is not known).

    Raises
    ------
    ValueError
        If ``recording`` is not a recording of the dataset, or ``path`` is not its file.
    FileNotFoundError, RawDataError, DeclarationError
        From the readers, :func:`check_log` and :func:`check_count_range` (raw counts, of a
        native CSV or a declared recording in ``counts``, beyond ``range_counts``).
    """
    _check_recording(path, recording, dataset)
    metadata: dict[str, Any] = _base_metadata(path, recording, dataset, imucal_version)
    if recording in dataset.readers:
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
        batches: list[Mapping[str, pa.Array | np.ndarray]] = []
        stream = io.ImuCsvStream(path)
        metadata.update(_ingest_imu_csv(stream, dataset, batches.append))
        table = pd.DataFrame(
            {
                name: np.concatenate([_numpy(batch[name]) for batch in batches])
                for name in _ingested_columns(stream)
            },
            copy=False,
        )
    metadata.update(_column_metadata(list(table.columns)))
    return table, metadata


def ingest_to_parquet(
    path: str | Path,
    recording: str,
    dataset: Dataset,
    imucal_version: str,
    out: str | Path,
    batch_bytes: int = io.BATCH_BYTES,
) -> dict:
    """Ingest one raw recording of a dataset into a parquet file (the ingest rule).

    A native IMU CSV is streamed: read in batches of ``batch_bytes``, checked, converted and
    written as parquet row groups, so memory stays bounded whatever the length of the log
    (24 h at 1 kHz: 86 M rows). The reference and declared recordings are read whole
    (:func:`ingest_recording`). Either way the file equals
    ``write_recording(*ingest_recording(...))``: the same rows, columns, metadata and errors.

    Parameters
    ----------
    path, recording, dataset, imucal_version
        As :func:`ingest_recording`.
    out : str or Path
        Target ``.parquet`` file, written atomically: on any error no file is left.
    batch_bytes : int
        Bytes of the CSV parsed per batch (the rows of a batch are one parquet row group).

    Returns
    -------
    dict
        The metadata written with the table (:func:`ingest_recording`), plus nothing else.

    Raises
    ------
    ValueError, FileNotFoundError, RawDataError, DeclarationError
        As :func:`ingest_recording`. A problem in a native CSV is raised after the whole file
        was read (the error names the first problem, as for the whole table).
    """
    _check_recording(path, recording, dataset)
    if recording in dataset.readers or recording == REFERENCE:
        table, metadata = ingest_recording(path, recording, dataset, imucal_version)
        io.write_recording(table, out, metadata)
        return metadata
    stream = io.ImuCsvStream(path, batch_bytes)
    columns = _ingested_columns(stream)
    dtypes = {name: np.int64 if name == SEQ else np.float64 for name in columns}
    with io.RecordingWriter(out, dtypes) as writer:
        metadata = _base_metadata(path, recording, dataset, imucal_version)
        metadata.update(_ingest_imu_csv(stream, dataset, writer.write))
        metadata.update(_column_metadata(columns))
        writer.close(metadata)
    return metadata


def _ingest_imu_csv(
    stream: io.ImuCsvStream,
    dataset: Dataset,
    sink: Callable[[Mapping[str, pa.Array | np.ndarray]], None],
) -> dict:
    """Check and convert a native CSV batch by batch; ``sink`` takes each batch's SI columns.

    Every check runs over the whole file before anything is returned: format problems first
    (raised by the stream), then time and packet order, then the count range. Once a problem
    is found no more batches go to ``sink``.
    """
    factors = _factors(dataset.sensitivity)
    order = LogChecks(stream.path, first_line=2)
    limits = CountRange(stream.path, dataset.count_range, first_line=2)
    extra = stream.extra_columns
    for batch in stream:
        order.update(batch.column(TIME).to_numpy(), batch.column(SEQ).to_numpy())
        limits.update({c: batch.column(c) for c in _SENSOR_COLUMN_NAMES}, batch.num_rows)
        if order.failed or limits.failed:
            continue
        si: dict[str, pa.Array | np.ndarray] = {TIME: batch.column(TIME), SEQ: batch.column(SEQ)}
        for sensor, names in SENSOR_COLUMNS.items():
            for name in names:
                # counts * sensitivity (one rounding, as counts_to_si); an empty cell stays null
                si[name] = pc.multiply(pc.cast(batch.column(name), pa.float64()), factors[sensor])
        for name in extra:
            si[name] = batch.column(name).to_numpy(zero_copy_only=False)
        sink(si)
    order.finish()
    limits.finish()
    return {
        "format": io.IMU_CSV_FORMAT,
        "clipped": limits.clipped,
        "sensitivity": dict(dataset.sensitivity),
        "first_line": 2,
        "sha256": stream.sha256,
    }


def _ingested_columns(stream: io.ImuCsvStream) -> list[str]:
    """Columns of an ingested native CSV: time, counter, sensors, then extras in file order."""
    return [
        TIME,
        SEQ,
        *(c for cols in SENSOR_COLUMNS.values() for c in cols),
        *stream.extra_columns,
    ]


def _numpy(values: pa.Array | np.ndarray) -> np.ndarray:
    """An ingested column as numpy (a float null is NaN: no sample)."""
    return values if isinstance(values, np.ndarray) else values.to_numpy(zero_copy_only=False)


def _column_metadata(columns: list[str]) -> dict:
    """``units``, ``sensors``, ``has_seq`` and ``extra_columns`` of an ingested table."""
    sensors = [s for s, cols in SENSOR_COLUMNS.items() if cols[0] in columns]
    extra = [c for c in columns if c not in (TIME, SEQ) and c not in _SENSOR_COLUMN_NAMES]
    units = {TIME: "s"}
    if SEQ in columns:
        units[SEQ] = "1"
    units.update({c: SI_UNITS[s] for s in sensors for c in SENSOR_COLUMNS[s]})
    units.update({c: "as in the source" for c in extra})
    return {"units": units, "sensors": sensors, "has_seq": SEQ in columns, "extra_columns": extra}


def _check_recording(path: str | Path, recording: str, dataset: Dataset) -> None:
    if recording not in dataset.recordings:
        raise ValueError(
            f"unknown recording {recording!r}; dataset {dataset.name!r} has "
            f"{sorted(dataset.recordings)}"
        )
    if recording in dataset.readers:
        if Path(path).resolve() != Path(dataset.recordings[recording]).resolve():
            raise ValueError(
                f"{path}: not the file of the declared recording {recording!r}; expected "
                f"{dataset.recordings[recording]}"
            )


def _base_metadata(path: str | Path, recording: str, dataset: Dataset, version: str) -> dict:
    return {
        "dataset": dataset.name,
        "recording": recording,
        "source": str(path),
        "imucal_version": version,
    }


_SENSOR_COLUMN_NAMES = tuple(c for cols in SENSOR_COLUMNS.values() for c in cols)


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
    clipped: dict[str, int] = {}
    for i, entry in enumerate(readers.declared_entries(dataset.readers[recording])):
        found = _check_declared_counts(entry, f"{where} (file {i + 1})", dataset.count_range)
        for sensor, rows in found.items():
            clipped[sensor] = clipped.get(sensor, 0) + rows
    if SEQ in table.columns:
        check_log(table, files[0]["path"] if len(files) == 1 else where, first_line or 0)
    meta: dict[str, Any] = {
        "format": "declared",
        "reader": dataset.readers[recording],
        "files": files,
        "sha256": files[0]["sha256"],
        "source_units": rec.metadata["source_units"],
        "clipped": clipped,
        "sensitivity": _declared_sensitivity(dataset.readers[recording]),
        "first_line": first_line if len(files) == 1 else None,
        "field_norm_t": dataset.field_norm_t,
    }
    for key in ("streams", "parts", "part_gap_s", "sorted_by_time", "time_units", "file_units"):
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


def _check_declared_counts(
    entry: Mapping[str, Any], where: str, limits: Mapping[str, tuple[int, int]]
) -> dict[str, int]:
    """The raw counts (``counts - zero_counts``, in the file's own axes) of a declared
    one-file entry in ``counts`` within the ADC's range; the file is read again for them, in
    its own row order so that the error names its line (its sample for MATLAB and HDF5).
    Returns the rows at a limit per sensor in counts (:func:`check_count_range`)."""
    sensors = [s for s, unit in (entry.get("units") or {}).items() if unit == "counts"]
    if not sensors:
        return {}
    wanted = {c for s in sensors for c in SENSOR_COLUMNS[s]}
    raw_entry = {
        **{k: v for k, v in entry.items() if k not in ("axes", "sort_by_time", "zero_counts")},
        "columns": {t: c for t, c in entry["columns"].items() if t in wanted},
        "units": dict.fromkeys(sensors, "counts"),
        "sensitivity": dict.fromkeys(sensors, 1.0),
        "zero_counts": {s: z for s, z in (entry.get("zero_counts") or {}).items() if s in sensors},
        "rate_hz": 1.0,  # rows in file order; their times are not needed here
    }
    counts = readers.read_entry(raw_entry, where=where, field_norm_t=1.0)
    return check_count_range(
        counts.table,
        entry["file"],
        {s: limits[s] for s in sensors},
        counts.metadata["first_line"],
    )


def _declared_sensitivity(declaration: Mapping[str, Any]) -> dict:
    """Sensitivities (SI per count) of the entries of a declaration, by sensor."""
    entries = [declaration]
    out: dict = {}
    while entries:
        entry = entries.pop(0)
        entries += list(entry.get("parts", [])) + list(entry.get("streams", []))
        out.update(entry.get("sensitivity") or {})
    return out
