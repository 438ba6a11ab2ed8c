"""A declared recording read into SI units: one file (:func:`read_entry`), ``streams`` merged on
time (:func:`merge_streams`) and ``parts`` concatenated in time.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from imucal import io
from imucal.columns import SENSOR_COLUMNS, SENSORS, SEQ, TIME
from imucal.io.readers.arrays import netcdf_time_and_units, read_arrays
from imucal.io.readers.conversion import integer_values, sensor_values, time_values
from imucal.io.readers.declaration import (
    READERS,
    SENSOR_TARGETS,
    DeclarationError,
    DeclaredRecording,
    check_targets,
)
from imucal.io.readers.table import read_table

#: Parts are separated by at least this much time (s) and by ten times their longest time step,
#: both far above the block-gap threshold of :mod:`imucal.segments.filtering`.
PART_GAP_S = 10.0


PART_GAP_STEPS = 10.0


def read_declared(
    declaration: Mapping[str, Any],
    *,
    where: str,
    field_norm_t: float | None = None,
    label_column: str | None = None,
) -> DeclaredRecording:
    """Read a declared recording (one file, ``streams`` or ``parts``) into SI units.

    Parameters
    ----------
    declaration : mapping
        The recording's mapping from ``dataset.yaml`` with ``file`` paths made absolute
        (:func:`imucal.io.dataset.read_dataset` does that).
    where : str
        ``"<dataset.yaml>: recordings.<name>"``, the prefix of every error message.
    field_norm_t : float, optional
        Local field norm, T; required when the magnetometer is in a physical unit (``T``,
        ``uT``, ``gauss`` or ``counts`` with a sensitivity in T).
    label_column : str, optional
        Source column with section labels (``sections.from_column``), returned as ``labels``.

    Returns
    -------
    DeclaredRecording

    Raises
    ------
    DeclarationError
        The declaration does not fit the file (unknown column, missing unit or sensitivity,
        bad axes, a sensor with only some of its axes, ...).
    RawDataError
        The file cannot be read as declared (unreadable cell, time going backwards, ...).
    FileNotFoundError
        A declared file does not exist.
    """
    if "parts" in declaration:
        parts = [
            _read_streams_or_entry(p, f"{where}.parts[{i}]", field_norm_t, label_column)
            for i, p in enumerate(declaration["parts"])
        ]
        rec = _concatenate_parts(parts, where)
    else:
        rec = _read_streams_or_entry(declaration, where, field_norm_t, label_column)
    if label_column is not None and rec.labels is None:
        raise DeclarationError(
            f"{where}", f"no stream has the section column {label_column!r}", "it in the file"
        )
    return rec


def _read_streams_or_entry(
    declaration: Mapping[str, Any], where: str, field_norm_t: float | None, label: str | None
) -> DeclaredRecording:
    if "streams" in declaration:
        streams = [
            read_entry(
                s, where=f"{where}.streams[{i}]", field_norm_t=field_norm_t, label_column=label
            )
            for i, s in enumerate(declaration["streams"])
        ]
        return merge_streams(streams, where)
    return read_entry(declaration, where=where, field_norm_t=field_norm_t, label_column=label)


def read_entry(
    entry: Mapping[str, Any],
    *,
    where: str,
    field_norm_t: float | None = None,
    label_column: str | None = None,
) -> DeclaredRecording:
    """Read one file as declared by ``entry`` (keys of ``docs/data-format.md``).

    Parameters and errors as :func:`read_declared`; ``label_column`` is optional here (a stream
    without it has ``labels`` None).
    """
    path = Path(entry["file"])
    if not path.is_file():
        raise FileNotFoundError(f"{where}.file: {path} not found; expected an existing file")
    columns = dict(entry.get("columns") or {})
    if not columns:
        raise DeclarationError(f"{where}.columns", "no column map", "target: source pairs")
    check_targets(columns, where)
    reader = entry["reader"]
    if reader == "table":
        raw, labels, first_line = read_table(entry, path, columns, where, label_column)
    elif reader in ("matlab", "hdf5", "netcdf"):
        raw, labels = read_arrays(entry, path, columns, where, label_column)
        first_line = None
    else:
        raise DeclarationError(f"{where}.reader", f"{reader!r}", f"one of {READERS}")
    netcdf = netcdf_time_and_units(entry, path, columns, raw, where) if reader == "netcdf" else {}
    n = len(next(iter(raw.values())))
    if n < 2:
        raise io.RawDataError(path, None, f"{n} sample(s)", "at least two samples")
    order = None
    if entry.get("sort_by_time", False):
        if TIME not in raw:
            raise DeclarationError(
                f"{where}.sort_by_time", "sort_by_time without a t_s column", "a t_s column"
            )
        order = np.argsort(raw[TIME], kind="stable")
        if np.array_equal(order, np.arange(n)):
            order = None
        else:
            raw = {k: v[order] for k, v in raw.items()}
            labels = None if labels is None else labels[order]
            first_line = None  # rows no longer follow the file's lines
    t_s = time_values(entry, raw, path, where, first_line)
    data: dict[str, np.ndarray] = {TIME: t_s}
    if SEQ in raw:
        data[SEQ] = integer_values(raw[SEQ], path, SEQ, first_line)
    units: dict[str, str] = {}
    sensors = []
    for sensor in SENSORS:
        values = sensor_values(entry, raw, sensor, path, where, first_line, field_norm_t)
        if values is None:
            continue
        sensors.append(sensor)
        units[sensor] = entry["units"][sensor]
        for k, name in enumerate(SENSOR_COLUMNS[sensor]):
            data[name] = values[:, k]
    extras = [c for c in columns if c not in data and c != TIME and c not in SENSOR_TARGETS]
    for name in extras:
        data[name] = raw[name]
    frame = pd.DataFrame(data, copy=False)
    info = {
        "reader": io.to_jsonable(entry),
        "files": [{"path": str(path), "sha256": io.sha256_file(path)}],
        "source_units": units,
        "sensors": sensors,
        "rows": int(n),
        "first_line": first_line,
        "sorted_by_time": order is not None,
        **netcdf,
    }
    return DeclaredRecording(frame, tuple(sensors), labels, t_s.copy(), info)


def merge_streams(streams: Sequence[DeclaredRecording], where: str) -> DeclaredRecording:
    """Merge streams on time: one row per distinct time, no sample invented.

    Rows are the union of the streams' timestamps, sorted (stable: equal times keep the order
    of the streams). Samples of different streams at exactly the same time share a row; the
    ``j``-th sample of a stream at a repeated time pairs with the ``j``-th of another stream at
    that time. A stream's columns are NaN on rows where it has no sample (never interpolated).

    Raises
    ------
    DeclarationError
        If two streams declare the same column, or two streams give ``seq``.
    """
    owner: dict[str, int] = {}
    for i, s in enumerate(streams):
        for c in s.table.columns:
            if c == TIME:
                continue
            if c in owner:
                raise DeclarationError(
                    f"{where}.streams[{i}].columns.{c}",
                    f"column {c!r} also comes from streams[{owner[c]}]",
                    "each column from one stream only",
                )
            owner[c] = i
    keyed = []
    for i, s in enumerate(streams):
        frame = s.table.copy()
        frame["_occ"] = frame.groupby(TIME, sort=False).cumcount()
        if s.labels is not None:
            frame["_label"] = s.labels
        keyed.append(frame)
    merged = keyed[0]
    for frame in keyed[1:]:
        if "_label" in merged and "_label" in frame:
            frame = frame.drop(columns="_label")
        merged = merged.merge(frame, on=[TIME, "_occ"], how="outer", sort=False)
    merged = merged.sort_values([TIME, "_occ"], kind="stable").reset_index(drop=True)
    labels = None
    if "_label" in merged:
        labels = merged.pop("_label").fillna("").to_numpy(dtype=str)
    merged = merged.drop(columns="_occ")
    if SEQ in merged and merged[SEQ].isna().any():
        raise DeclarationError(
            f"{where}.streams[{owner[SEQ]}].columns.seq",
            "a packet counter in one stream of several (rows of the others would have none)",
            "seq only in a one-file recording",
        )
    sensors = tuple(s for s in SENSORS if any(s in st.sensors for st in streams))
    order = [TIME, *([SEQ] if SEQ in merged else [])]
    order += [c for s in sensors for c in SENSOR_COLUMNS[s]]
    order += [c for c in merged.columns if c not in order]
    info = {
        "streams": [s.metadata for s in streams],
        "files": [f for s in streams for f in s.metadata["files"]],
        "source_units": {k: v for s in streams for k, v in s.metadata["source_units"].items()},
        "sensors": list(sensors),
    }
    return DeclaredRecording(merged[order], sensors, labels, streams[0].primary_t_s, info)


def _concatenate_parts(parts: Sequence[DeclaredRecording], where: str) -> DeclaredRecording:
    """Parts one after another: part ``k`` is shifted to start a gap after part ``k - 1`` ends.

    The gap is ``max(PART_GAP_S, PART_GAP_STEPS * longest time step of the parts)``, so the
    low-pass sees each part as its own block; no sample is added in it.
    """
    sensor_sets = [set(p.sensors) for p in parts]
    if any(s != sensor_sets[0] for s in sensor_sets):
        raise DeclarationError(
            f"{where}.parts",
            f"parts with different sensors {[sorted(s) for s in sensor_sets]}",
            "the same sensors in every part",
        )
    steps = [float(np.max(np.diff(p.table[TIME].to_numpy()))) for p in parts]
    gap = max(PART_GAP_S, PART_GAP_STEPS * max(steps))
    frames, labels, bounds = [], [], []
    start_row, end_t = 0, None
    for k, p in enumerate(parts):
        t = p.table[TIME].to_numpy()
        shift = 0.0 if end_t is None else end_t + gap - t[0]
        frame = p.table.copy()
        frame[TIME] = t + shift
        frames.append(frame)
        labels.append(p.labels if p.labels is not None else np.full(len(frame), "", dtype=object))
        end_t = float(frame[TIME].iloc[-1])
        bounds.append(
            {
                "part": k,
                "start_row": start_row,
                "end_row": start_row + len(frame),
                "t_start_s": float(frame[TIME].iloc[0]),
                "t_end_s": end_t,
                "shift_s": shift,
                "files": [f["path"] for f in p.metadata["files"]],
            }
        )
        start_row += len(frame)
    table = pd.concat(frames, ignore_index=True)
    has_labels = any(p.labels is not None for p in parts)
    info = {
        "parts": bounds,
        "part_gap_s": gap,
        "part_readers": [p.metadata for p in parts],
        "files": [f for p in parts for f in p.metadata["files"]],
        "source_units": {k: v for p in parts for k, v in p.metadata["source_units"].items()},
        "sensors": list(parts[0].sensors),
    }
    return DeclaredRecording(
        table,
        parts[0].sensors,
        np.concatenate(labels).astype(str) if has_labels else None,
        parts[0].primary_t_s,
        info,
    )
