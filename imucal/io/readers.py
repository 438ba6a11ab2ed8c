"""Declared readers: recordings in other people's formats, described in ``dataset.yaml``.

A recording of ``dataset.yaml`` is either a file name (the native IMU CSV, read by
:func:`imucal.io.read_imu_csv`) or a mapping that declares how to read it
(``docs/data-format.md``, section "Declared recordings"):

* one file: ``reader`` (``table``, ``matlab``, ``hdf5`` or ``netcdf``), ``file`` and a column map;
* ``streams``: one file per sensor (each a one-file entry), merged on time;
* ``parts``: one-file or ``streams`` entries concatenated in time.

This module is the file access of those declarations (like :mod:`imucal.io` for the native
formats): it reads the columns, converts them to the SI units of :mod:`imucal.columns`, applies
the declared axis permutation and signs, and merges streams and parts. It adds no sample and
fills no value: a sensor without a sample at a row's time holds NaN on that row (all three axes).

Every problem raises :class:`DeclarationError` (a declaration that does not fit the file, the
message names the ``dataset.yaml`` key path and the column) or :class:`imucal.io.RawDataError`
(the file breaks its declared format; the message names the file and the line or row).

The module is long (about 1150 lines): every declared reader (tables, MATLAB v5/v7.3,
HDF5, netCDF4, streams, parts, section lists, 2-D arrays) shares the declaration's checks and the
error messages naming the ``dataset.yaml`` key; splitting it by format would repeat them.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from imucal import io
from imucal.columns import AXES, SENSOR_COLUMNS, SENSORS, SEQ, TIME
from imucal.constants import STANDARD_GRAVITY_M_S2

#: Reader names of a one-file entry.
READERS = ("table", "matlab", "hdf5", "netcdf")
#: Delimiters of the table reader; ``whitespace`` is any run of blanks and tabs.
DELIMITERS = {",": ",", ";": ";", "\t": "\t", "whitespace": r"\s+"}
#: Accepted source units per sensor and their factor to SI (None: needs ``sensitivity``, or is
#: taken as it is for the already normalised magnetometer).
UNIT_FACTORS: dict[str, dict[str, float | None]] = {
    "acc": {"m/s^2": 1.0, "g": STANDARD_GRAVITY_M_S2, "counts": None},
    "gyr": {"rad/s": 1.0, "deg/s": math.pi / 180.0, "mrad/s": 1e-3, "counts": None},
    "mag": {"T": 1.0, "uT": 1e-6, "gauss": 1e-4, "counts": None, "normalised": None},
}
#: Magnetometer units that are a physical field (converted to tesla, then divided by the
#: dataset's ``field_norm_t``).
PHYSICAL_MAG_UNITS = ("T", "uT", "gauss", "counts")
#: SI unit of a count's ``sensitivity`` in a declared entry.
SENSITIVITY_UNITS = {"acc": "m/s^2", "gyr": "rad/s", "mag": "T"}
#: Target names besides ``t_s``, ``seq`` and the sensor columns (kept as they are in the source).
EXTRA_NAME = re.compile(r"^[a-z][a-z0-9_]*$")
#: Parts are separated by at least this much time (s) and by ten times their longest time step,
#: both far above the block-gap threshold of :mod:`imucal.segments.filtering`.
PART_GAP_S = 10.0
PART_GAP_STEPS = 10.0


class DeclarationError(ValueError):
    """A recording declaration of ``dataset.yaml`` does not fit its file.

    The message reads ``"<where>: <what was found>; expected <what>"`` with ``where`` the
    dataset.yaml file and the key path, e.g. ``.../dataset.yaml: recordings.static.columns.acc_x``.
    """

    def __init__(self, where: str, found: str, expected: str) -> None:
        self.where = where
        super().__init__(f"{where}: {found}; expected {expected}")


@dataclass(frozen=True)
class DeclaredRecording:
    """A declared recording read and converted to SI units.

    Attributes
    ----------
    table : DataFrame, shape (n, k)
        ``t_s`` (float64, s, non-decreasing), ``seq`` (int64) when declared, the columns of each
        sensor present (float64, SI: acc m/s^2, gyr rad/s, mag normalised to the field norm; NaN
        on rows where that sensor has no sample), then extra columns as in the source.
    sensors : tuple of str
        Sensors present, in :data:`imucal.columns.SENSORS` order.
    labels : ndarray of str, shape (n,), or None
        The values of the section label column (``sections.from_column``) per row, "" on rows
        of a stream without it; None when none was asked for.
    primary_t_s : ndarray, shape (m,)
        ``t_s`` of the samples of the first stream (the first part's first stream for parts):
        sample index ``k`` of a section list is the time ``primary_t_s[k]``.
    metadata : dict
        ``reader`` (declaration with file paths), ``files`` (``path``, ``sha256``),
        ``source_units``, ``sensors``, ``streams`` and ``parts`` (row ranges and time shifts).
    """

    table: pd.DataFrame
    sensors: tuple
    labels: np.ndarray | None
    primary_t_s: np.ndarray
    metadata: dict = field(default_factory=dict)


# --------------------------------------------------------------------------------------------
# Entry point


def declared_entries(declaration: Mapping[str, Any]) -> list[Mapping[str, Any]]:
    """The one-file entries of a declaration (a file, its streams, parts of either), in order."""
    if "parts" in declaration:
        return [e for part in declaration["parts"] for e in declared_entries(part)]
    if "streams" in declaration:
        return list(declaration["streams"])
    return [declaration]


def declared_files(declaration: Mapping[str, Any]) -> list[Path]:
    """All files a declaration reads, in order (for Snakemake inputs and checksums)."""
    return [Path(entry["file"]) for entry in declared_entries(declaration)]


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


# --------------------------------------------------------------------------------------------
# One file


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
    _check_targets(columns, where)
    reader = entry["reader"]
    if reader == "table":
        raw, labels, first_line = _read_table(entry, path, columns, where, label_column)
    elif reader in ("matlab", "hdf5", "netcdf"):
        raw, labels = _read_arrays(entry, path, columns, where, label_column)
        first_line = None
    else:
        raise DeclarationError(f"{where}.reader", f"{reader!r}", f"one of {READERS}")
    netcdf = _netcdf_time_and_units(entry, path, columns, raw, where) if reader == "netcdf" else {}
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
    t_s = _time(entry, raw, path, where, first_line)
    data: dict[str, np.ndarray] = {TIME: t_s}
    if SEQ in raw:
        data[SEQ] = _integers(raw[SEQ], path, SEQ, first_line)
    units: dict[str, str] = {}
    sensors = []
    for sensor in SENSORS:
        values = _sensor(entry, raw, sensor, path, where, first_line, field_norm_t)
        if values is None:
            continue
        sensors.append(sensor)
        units[sensor] = entry["units"][sensor]
        for k, name in enumerate(SENSOR_COLUMNS[sensor]):
            data[name] = values[:, k]
    extras = [c for c in columns if c not in data and c != TIME and c not in _SENSOR_TARGETS]
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


_SENSOR_TARGETS = {c for cols in SENSOR_COLUMNS.values() for c in cols}


def _check_targets(columns: Mapping[str, Any], where: str) -> None:
    for target, source in columns.items():
        known = target in (TIME, SEQ) or target in _SENSOR_TARGETS or EXTRA_NAME.match(target)
        if not known:
            raise DeclarationError(
                f"{where}.columns.{target}",
                f"target {target!r}",
                "t_s, seq, acc_x..mag_z or an extra name of lower-case letters, digits and _",
            )
        if not (_is_index(source) or isinstance(source, str) or _is_array_column(source)):
            raise DeclarationError(
                f"{where}.columns.{target}",
                f"source {source!r}",
                "a column name, a 0-based column index or [array, 0-based column index]",
            )


def _is_index(source: Any) -> bool:
    return isinstance(source, int) and not isinstance(source, bool) and source >= 0


def _is_array_column(source: Any) -> bool:
    """``[array, index]``: a column of a named 2-D array (MATLAB variable, HDF5 dataset)."""
    return (
        isinstance(source, (list, tuple))
        and len(source) == 2
        and isinstance(source[0], str)
        and _is_index(source[1])
    )


def _read_table(
    entry: Mapping[str, Any],
    path: Path,
    columns: Mapping[str, Any],
    where: str,
    label_column: str | None,
) -> tuple[dict[str, np.ndarray], np.ndarray | None, int]:
    """Delimited text: returns raw float columns by target, the labels and the first data line."""
    delimiter = entry.get("delimiter", ",")
    if delimiter not in DELIMITERS:
        raise DeclarationError(f"{where}.delimiter", f"{delimiter!r}", f"one of {list(DELIMITERS)}")
    skip = int(entry.get("skip_lines", 0))
    header = bool(entry.get("header", True))
    try:
        text = pd.read_csv(
            path,
            sep=DELIMITERS[delimiter],
            header=0 if header else None,
            skiprows=skip,
            dtype=str,
            keep_default_na=False,
            skip_blank_lines=False,
            engine="python" if delimiter == "whitespace" else "c",
            encoding="utf-8-sig",
        )
    except pd.errors.EmptyDataError:
        raise io.RawDataError(
            path, skip + 1, "no header and no data after the skipped lines", "a table"
        ) from None
    except pd.errors.ParserError as err:
        raise io.RawDataError(
            path, None, f"not a {delimiter!r}-delimited table ({err})", "equal cells per line"
        ) from None
    first_line = skip + (2 if header else 1)
    names = [str(c) for c in text.columns]
    if text.shape[0] == 0:
        raise io.RawDataError(path, first_line, "no data rows", "at least one row of samples")
    blank = (text == "").all(axis=1).to_numpy()
    if blank.any():
        row = int(np.flatnonzero(blank)[0])
        raise io.RawDataError(path, first_line + row, "an empty line", "one row per line")

    def position(target: str, source: Any, key: str) -> int:
        if _is_array_column(source):
            raise DeclarationError(
                key,
                f"source {list(source)!r} (a column of a named array) in the table {path}",
                "a column name or a 0-based column index (arrays are for matlab and hdf5)",
            )
        if isinstance(source, int):
            if source >= len(names):
                raise DeclarationError(
                    key,
                    f"column index {source} not in {path} ({len(names)} columns: {names})",
                    f"an index 0..{len(names) - 1}",
                )
            return source
        if not header:
            raise DeclarationError(
                key,
                f"column {source!r} by name, but header is false in {path}",
                "a 0-based column index (the file has no header line)",
            )
        if source not in names:
            raise DeclarationError(
                key,
                f"column {source!r} not in {path} (columns: {', '.join(names)})",
                "a column of its header line",
            )
        return names.index(source)

    raw: dict[str, np.ndarray] = {}
    for target, source in columns.items():
        k = position(target, source, f"{where}.columns.{target}")
        raw[target] = _numbers(text.iloc[:, k], path, names[k] if header else k, first_line)
    labels = None
    if label_column is not None:
        try:
            k = position("section", label_column, f"{where}: sections.from_column")
        except DeclarationError:
            k = None
        if k is not None:
            labels = text.iloc[:, k].to_numpy(dtype=str)
    return raw, labels, first_line


def _numbers(cells: pd.Series, path: Path, column: Any, first_line: int) -> np.ndarray:
    """Cells to float64; an empty cell is NaN, anything else that is not a number is an error."""
    values = pd.to_numeric(cells.str.strip(), errors="coerce").to_numpy(dtype=float)
    bad = (
        np.isnan(values)
        & (cells.str.strip() != "").to_numpy()
        & ~cells.str.strip().str.lower().isin(["nan"]).to_numpy()
    )
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise io.RawDataError(
            path, first_line + row, f"column {column!r} holds {cells.iloc[row]!r}", "a number"
        )
    return values


def _read_arrays(
    entry: Mapping[str, Any],
    path: Path,
    columns: Mapping[str, Any],
    where: str,
    label_column: str | None,
) -> tuple[dict[str, np.ndarray], np.ndarray | None]:
    """MATLAB (v5 or v7.3) or HDF5 columns, each from one of three sources.

    An integer is a column of the 2-D array named by ``variable`` / ``dataset``; a name is a
    vector (e.g. a ``1 x N`` time variable); ``[array, index]`` is a column of the named 2-D
    array, read along the dimension that holds the samples (so a ``3 x N`` array beside a
    ``1 x N`` time vector needs no ``transpose``). Every column must have the same length.
    """
    reader = entry["reader"]
    key = "dataset" if reader == "hdf5" else "variable"
    name = entry.get(key)
    transpose = bool(entry.get("transpose", False))
    store = _ArrayFile(path, reader)
    raw: dict[str, np.ndarray] = {}
    array = None
    if name is not None:
        array = store.get(name, f"{where}.{key}")
        if array.ndim != 2:
            raise DeclarationError(
                f"{where}.{key}", f"{name!r} in {path} has shape {array.shape}", "a 2-D array"
            )
        if transpose:
            array = array.T
    for target, source in columns.items():
        if not isinstance(source, str):
            continue
        vector = store.get(source, f"{where}.columns.{target}")
        if vector.ndim == 2 and 1 in vector.shape:
            vector = vector.reshape(-1)
        if vector.ndim != 1:
            raise DeclarationError(
                f"{where}.columns.{target}",
                f"{source!r} in {path} has shape {vector.shape}",
                f"a vector (or a column of a 2-D array: an index with '{key}', or [array, index])",
            )
        raw[target] = np.asarray(vector, dtype=float)
    for target, source in columns.items():
        if not _is_index(source):
            continue
        if array is None:
            raise DeclarationError(
                f"{where}.columns.{target}",
                f"column index {source} without '{key}' in {where}",
                f"'{key}' naming the 2-D array of the indices, or [array, index]",
            )
        if source >= array.shape[1]:
            raise DeclarationError(
                f"{where}.columns.{target}",
                f"column index {source} not in {name!r} of {path} (shape {array.shape}"
                f"{', transposed' if transpose else ''})",
                f"an index 0..{array.shape[1] - 1}",
            )
        raw[target] = np.asarray(array[:, source], dtype=float)
    n_samples = len(next(iter(raw.values()))) if raw else None
    arrays: dict[str, np.ndarray] = {}
    for target, source in columns.items():
        if not _is_array_column(source):
            continue
        array_name, index = source
        key_path = f"{where}.columns.{target}"
        if array_name not in arrays:
            values = store.get(array_name, key_path)
            if values.ndim != 2:
                raise DeclarationError(
                    key_path,
                    f"{array_name!r} in {path} has shape {values.shape}",
                    "a 2-D array (samples x columns or columns x samples)",
                )
            if n_samples is None:
                n_samples = max(values.shape)
            if values.shape[0] != n_samples and values.shape[1] == n_samples:
                values = values.T  # columns x samples, e.g. a 3 x N array
            if values.shape[0] != n_samples:
                raise DeclarationError(
                    key_path,
                    f"{array_name!r} in {path} has shape {values.shape}, no dimension of "
                    f"{n_samples} samples (the length of the other columns)",
                    "one dimension with one entry per sample",
                )
            arrays[array_name] = values
        if index >= arrays[array_name].shape[1]:
            raise DeclarationError(
                key_path,
                f"column index {index} not in {array_name!r} of {path} ({n_samples} samples "
                f"x {arrays[array_name].shape[1]} columns)",
                f"an index 0..{arrays[array_name].shape[1] - 1}",
            )
        raw[target] = np.asarray(arrays[array_name][:, index], dtype=float)
    lengths = {t: v.size for t, v in raw.items()}
    if len(set(lengths.values())) > 1:
        raise DeclarationError(f"{where}.columns", f"columns of lengths {lengths}", "equal lengths")
    raw = {target: raw[target] for target in columns}
    labels = None
    if label_column is not None and name is None and store.has(label_column):
        labels = np.asarray(store.get(label_column, where), dtype=str).reshape(-1)
    return raw, labels


class _ArrayFile:
    """Named arrays of a MATLAB v5 file (scipy) or an HDF5 / MATLAB v7.3 file (h5py)."""

    def __init__(self, path: Path, reader: str) -> None:
        import h5py

        self.path = path
        self.hdf5 = h5py.is_hdf5(path)
        # MATLAB v7.3 writes column-major arrays: h5py sees them transposed
        self.matlab_order = reader == "matlab" and self.hdf5
        if reader == "hdf5" and not self.hdf5:
            raise io.RawDataError(path, None, "not an HDF5 file", "an HDF5 (or MATLAB v7.3) file")
        if reader == "netcdf" and not self.hdf5:
            raise io.RawDataError(
                path,
                None,
                "not an HDF5 file (netCDF3 classic or 64-bit offset?)",
                "a netCDF4 file (HDF5 underneath)",
            )
        self.netcdf = reader == "netcdf"
        if self.hdf5:
            self.names = self._hdf5_names()
        else:
            from scipy import io as sio

            try:
                self.mat = sio.loadmat(path)
            except (ValueError, TypeError, NotImplementedError) as err:
                raise io.RawDataError(
                    path, None, f"unreadable ({err})", "a MATLAB v5 file"
                ) from None
            self.names = sorted(k for k in self.mat if not k.startswith("__"))

    def _hdf5_names(self) -> list[str]:
        import h5py

        names: list[str] = []
        with h5py.File(self.path, "r") as f:
            f.visititems(lambda n, obj: names.append(n) if isinstance(obj, h5py.Dataset) else None)
        return names

    def has(self, name: str) -> bool:
        return name.strip("/") in self.names

    def get(self, name: str, key: str) -> np.ndarray:
        if not self.has(name):
            what = "datasets" if self.hdf5 and not self.matlab_order else "variables"
            raise DeclarationError(
                key,
                f"{name!r} not in {self.path} ({what}: {', '.join(self.names) or 'none'})",
                f"one of its {what}",
            )
        if not self.hdf5:
            return np.asarray(self.mat[name])
        import h5py

        with h5py.File(self.path, "r") as f:
            data = f[name.strip("/")]
            array = np.asarray(data[()])
            if self.netcdf:
                array = _cf_unpacked(array, data.attrs)
        return array.T if self.matlab_order else array

    def attribute(self, name: str, attribute: str) -> str | None:
        """A text attribute of a dataset (e.g. a netCDF variable's ``units``), or None."""
        import h5py

        with h5py.File(self.path, "r") as f:
            value = f[name.strip("/")].attrs.get(attribute)
        if isinstance(value, np.ndarray) and value.size == 1:
            value = value.reshape(-1)[0]
        if isinstance(value, bytes):
            value = value.decode("utf-8", "replace")
        return value if isinstance(value, str) else None


def _cf_unpacked(array: np.ndarray, attrs: Mapping[str, Any]) -> np.ndarray:
    """A netCDF variable as numbers: ``_FillValue`` and ``missing_value`` to NaN, then
    ``scale_factor`` and ``add_offset`` (CF packing) applied."""
    if array.dtype.kind not in "iuf":
        return array
    values = array.astype(float)
    for key in ("_FillValue", "missing_value"):
        fill = attrs.get(key)
        if fill is not None:
            fill = np.asarray(fill, dtype=float).reshape(-1)
            values[np.isin(values, fill[np.isfinite(fill)])] = np.nan
    scale = attrs.get("scale_factor")
    offset = attrs.get("add_offset")
    if scale is not None:
        values = values * float(np.asarray(scale).reshape(-1)[0])
    if offset is not None:
        values = values + float(np.asarray(offset).reshape(-1)[0])
    return values


#: Time units of a netCDF (CF) time variable, ``"<unit> since <origin>"``, in seconds.
CF_TIME_UNITS = {
    "days": 86400.0, "day": 86400.0, "d": 86400.0,
    "hours": 3600.0, "hour": 3600.0, "h": 3600.0,
    "minutes": 60.0, "minute": 60.0, "min": 60.0,
    "seconds": 1.0, "second": 1.0, "secs": 1.0, "sec": 1.0, "s": 1.0,
    "milliseconds": 1e-3, "millisecond": 1e-3, "ms": 1e-3,
    "microseconds": 1e-6, "microsecond": 1e-6, "us": 1e-6,
}  # fmt: skip
#: Spellings of a netCDF variable's ``units`` attribute -> the declared unit they mean.
CF_SENSOR_UNITS = {
    "m/s2": "m/s^2", "m/s^2": "m/s^2", "m s-2": "m/s^2", "ms-2": "m/s^2", "m.s-2": "m/s^2",
    "rad/s": "rad/s", "rad s-1": "rad/s", "mrad/s": "mrad/s", "mrad s-1": "mrad/s",
    "deg/s": "deg/s", "degree/s": "deg/s", "degrees/s": "deg/s", "deg s-1": "deg/s",
    "ut": "uT", "microtesla": "uT", "t": "T", "tesla": "T", "gauss": "gauss",
}  # fmt: skip


def _netcdf_time_and_units(
    entry: Mapping[str, Any],
    path: Path,
    columns: Mapping[str, Any],
    raw: dict[str, np.ndarray],
    where: str,
) -> dict:
    """netCDF4: the time variable decoded, the declared units checked against the file's.

    A ``t_s`` variable whose ``units`` attribute reads ``"<unit> since <origin>"`` (CF) becomes
    seconds since that origin (``raw`` changed in place; ``rate_hz`` then must not be given). A
    sensor column from a variable with a ``units`` attribute the reader knows must agree with
    ``units.<sensor>`` of the declaration.

    Returns
    -------
    dict
        ``time_units`` (the attribute as found) when the time was decoded, and ``file_units``
        (target -> the variable's ``units`` attribute) for the metadata.
    """
    store = _ArrayFile(path, "netcdf")
    info: dict = {}
    source = columns.get(TIME)
    if isinstance(source, str):
        found = store.attribute(source, "units")
        match = re.match(r"^\s*(\w+)\s+since\s+(.+?)\s*$", found or "")
        if match:
            unit = match.group(1).lower()
            if unit not in CF_TIME_UNITS:
                raise DeclarationError(
                    f"{where}.columns.{TIME}",
                    f"time variable {source!r} of {path} in {found!r}",
                    f"'<unit> since <origin>' with a unit of {sorted(set(CF_TIME_UNITS))}",
                )
            if entry.get("rate_hz") is not None:
                raise DeclarationError(
                    f"{where}.rate_hz",
                    f"rate_hz beside the time variable {source!r} in {found!r}",
                    "no rate_hz (the time variable gives the times)",
                )
            raw[TIME] = raw[TIME] * CF_TIME_UNITS[unit]
            info["time_units"] = found
    file_units = {}
    for target, src in columns.items():
        sensor = target.split("_", 1)[0] if target in _SENSOR_TARGETS else None
        name = src[0] if _is_array_column(src) else src if isinstance(src, str) else None
        if name is None:
            continue
        found = store.attribute(name, "units")
        if found is None:
            continue
        file_units[target] = found
        meaning = CF_SENSOR_UNITS.get(found.strip().lower()) if sensor else None
        declared = (entry.get("units") or {}).get(sensor) if sensor else None
        if meaning and declared not in (None, "counts") and meaning != declared:
            raise DeclarationError(
                f"{where}.units.{sensor}",
                f"{declared!r}, but variable {name!r} of {path} says units {found!r}",
                f"the file's unit ({meaning!r})",
            )
    if file_units:
        info["file_units"] = file_units
    return info


# --------------------------------------------------------------------------------------------
# Time, counters and sensors


def _time(
    entry: Mapping[str, Any],
    raw: Mapping[str, np.ndarray],
    path: Path,
    where: str,
    first_line: int | None,
) -> np.ndarray:
    """``t_s`` from the time column, or ``k / rate_hz``; checked finite and non-decreasing."""
    rate = entry.get("rate_hz")
    if rate is not None and not (
        isinstance(rate, (int, float)) and math.isfinite(rate) and rate > 0
    ):
        raise DeclarationError(f"{where}.rate_hz", f"{rate!r}", "a positive number of Hz")
    if TIME not in raw:
        if rate is None:
            raise DeclarationError(
                f"{where}.rate_hz", "no t_s column and no rate_hz", "one of them (Hz)"
            )
        n = len(next(iter(raw.values())))
        return np.arange(n) / float(rate)
    # with rate_hz the t_s column is a sample counter (e.g. n_samples): t_s = counter / rate
    t = raw[TIME] if rate is None else raw[TIME] / float(rate)
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise io.RawDataError(
            path, _line(first_line, bad[0]), f"t_s is {float(t[bad[0]])}", "a finite time in s"
        )
    back = np.flatnonzero(np.diff(t) < 0)
    if back.size:
        i = int(back[0]) + 1
        line = _line(first_line, i)
        row = "" if line is not None else f" (data row {i + 1}, 1-based)"
        raise io.RawDataError(
            path,
            line,
            f"t_s {float(t[i])!r} s{row} is earlier than {float(t[i - 1])!r} s on the row before "
            f"({back.size} such step(s))",
            f"non-decreasing time; if the rows are out of time order on purpose (e.g. grouped by "
            f"section), declare {where}.sort_by_time: true to sort them by t_s",
        )
    if t[-1] == t[0]:
        raise io.RawDataError(path, None, f"t_s stays at {float(t[0])!r} s", "a time that advances")
    return np.asarray(t, dtype=float)


def _line(first_line: int | None, row: int) -> int | None:
    return None if first_line is None else first_line + int(row)


def _integers(values: np.ndarray, path: Path, name: str, first_line: int | None) -> np.ndarray:
    bad = np.flatnonzero(~np.isfinite(values) | (values != np.round(values)))
    if bad.size:
        raise io.RawDataError(
            path, _line(first_line, bad[0]), f"{name} is {values[bad[0]]}", "an integer counter"
        )
    return values.astype(np.int64)


def _sensor(
    entry: Mapping[str, Any],
    raw: Mapping[str, np.ndarray],
    sensor: str,
    path: Path,
    where: str,
    first_line: int | None,
    field_norm_t: float | None,
) -> np.ndarray | None:
    """One sensor's three columns in SI units, axes applied; None when it is not declared."""
    names = SENSOR_COLUMNS[sensor]
    given = [c for c in names if c in raw]
    if not given:
        for key in ("units", "sensitivity", "zero_counts", "axes"):
            if sensor in (entry.get(key) or {}):
                raise DeclarationError(
                    f"{where}.{key}.{sensor}",
                    f"{sensor} has a {key} entry but no column",
                    f"columns {', '.join(names)} in {where}.columns",
                )
        return None
    if len(given) < 3:
        missing = [c for c in names if c not in raw]
        raise DeclarationError(
            f"{where}.columns.{missing[0]}",
            f"{sensor} has column(s) {given} but not {missing}",
            f"all three of {', '.join(names)}",
        )
    x = np.column_stack([raw[c] for c in names])
    _check_rows(x, sensor, names, path, first_line)
    unit = (entry.get("units") or {}).get(sensor)
    if unit not in UNIT_FACTORS[sensor]:
        raise DeclarationError(
            f"{where}.units.{sensor}",
            "missing" if unit is None else f"unit {unit!r}",
            f"one of {list(UNIT_FACTORS[sensor])}",
        )
    zero = (entry.get("zero_counts") or {}).get(sensor)
    if unit == "counts":
        factor = (entry.get("sensitivity") or {}).get(sensor)
        if not (isinstance(factor, (int, float)) and math.isfinite(factor) and factor > 0):
            raise DeclarationError(
                f"{where}.sensitivity.{sensor}",
                "missing" if factor is None else f"{factor!r}",
                f"a positive number of {SENSITIVITY_UNITS[sensor]} per count for units.{sensor}: counts",
            )
        if zero is not None:
            x = x - float(zero)
        x = x * float(factor)
    else:
        for key, value in (
            ("sensitivity", (entry.get("sensitivity") or {}).get(sensor)),
            ("zero_counts", zero),
        ):
            if value is not None:
                raise DeclarationError(
                    f"{where}.{key}.{sensor}",
                    f"{key} given for units.{sensor}: {unit}",
                    "it only with units counts",
                )
        factor = UNIT_FACTORS[sensor][unit]
        if factor is not None:
            x = x * factor
    if sensor == "mag" and unit in PHYSICAL_MAG_UNITS:
        if field_norm_t is None:
            raise DeclarationError(
                f"{where}.units.mag",
                f"the magnetometer in {unit!r} but dataset.yaml has no field_norm_t",
                "the local field norm in tesla as field_norm_t (the ingested magnetometer is "
                "normalised by it)",
            )
        x = x / float(field_norm_t)
    axes = (entry.get("axes") or {}).get(sensor)
    if axes is not None:
        x = x @ axis_matrix(axes, f"{where}.axes.{sensor}").T
    return x


def _check_rows(
    x: np.ndarray, sensor: str, names: Sequence[str], path: Path, first_line: int | None
) -> None:
    """Per row the three axes are all numbers (a sample) or all empty (none); never part."""
    finite = np.isfinite(x)
    some = finite.any(axis=1)
    partial = some & ~finite.all(axis=1)
    if partial.any():
        row = int(np.flatnonzero(partial)[0])
        empty = [c for c, ok in zip(names, finite[row]) if not ok]
        raise io.RawDataError(
            path,
            _line(first_line, row),
            f"{', '.join(empty)} empty but not the other {sensor} column(s)"
            + ("" if first_line is not None else f" (sample {row + 1}, counted from 1)"),
            f"all three {sensor} values (a sample) or none",
        )
    if not some.any():
        raise io.RawDataError(path, None, f"{sensor} is empty on every row", "values in it")


def axis_matrix(axes: Sequence[str], key: str = "axes") -> np.ndarray:
    """Signed permutation matrix ``P`` of an ``axes`` declaration: ``target = P @ source``.

    Parameters
    ----------
    axes : sequence of 3 str
        Target axis ``i`` is ``axes[i]`` of the source, e.g. ``['x', '-y', 'z']`` flips y,
        ``['y', 'x', '-z']`` swaps x and y and flips z.
    key : str
        Key path for the error message.

    Returns
    -------
    ndarray, shape (3, 3)

    Raises
    ------
    DeclarationError
        If an item is not ``[+-]x|y|z`` or a source axis is used twice.
    """
    items = list(axes) if isinstance(axes, (list, tuple)) else None
    pattern = re.compile(r"^([+-]?)([xyz])$")
    matches = (
        [pattern.match(str(a)) for a in items] if items is not None and len(items) == 3 else None
    )
    if matches is None or not all(matches):
        raise DeclarationError(key, f"{axes!r}", "three items like [x, -y, z] (signed source axes)")
    sources = [m.group(2) for m in matches]
    if len(set(sources)) != 3:
        raise DeclarationError(
            key, f"{axes!r} uses a source axis twice", "a permutation of x, y, z"
        )
    matrix = np.zeros((3, 3))
    for i, m in enumerate(matches):
        matrix[i, AXES.index(m.group(2))] = -1.0 if m.group(1) == "-" else 1.0
    return matrix


# --------------------------------------------------------------------------------------------
# Streams and parts


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


# --------------------------------------------------------------------------------------------
# Section lists


#: Meaning of the labels of a Ferraris session (mad-lab-fau/imucal): ``<axis>_p`` a static face
#: with that axis pointing up, ``<axis>_a`` pointing down, ``<axis>_rot`` a full turn about it.
FERRARIS_LABELS: dict[str, dict] = {
    **{f"{a}_p": {"kind": "position", "up": f"+{a}"} for a in AXES},
    **{f"{a}_a": {"kind": "position", "up": f"-{a}"} for a in AXES},
    **{f"{a}_rot": {"kind": "phase", "axis": a, "angle_deg": 360.0} for a in AXES},
}
#: Optional columns of a CSV section list besides ``label``, ``start``, ``end``.
SECTION_CSV_OPTIONAL = ("kind", "axis", "up", "angle_deg", "rate_dps")


def read_sections(
    spec: Mapping[str, Any],
    *,
    where: str,
    t_s: np.ndarray,
    primary_t_s: np.ndarray,
    labels: np.ndarray | None = None,
) -> list[dict]:
    """Sections of a recording as manual segment entries (the ``segments`` override format).

    Parameters
    ----------
    spec : mapping
        The ``sections`` declaration: ``recording``, and ``file`` with ``format``
        (``ferraris_json`` or ``csv``) and ``index`` (``sample`` or ``time``), or
        ``from_column``; optional ``labels`` (label -> kind, axis, up, angle_deg, rate_dps).
    where : str
        ``"<dataset.yaml>: sections"``, prefix of the error messages.
    t_s : ndarray, shape (n,)
        Times of the ingested recording, s.
    primary_t_s : ndarray, shape (m,)
        Times of the samples a sample index counts (the first stream of the recording), s.
    labels : ndarray of str, shape (n,), optional
        The ``from_column`` value of every row of the ingested recording.

    Returns
    -------
    list of dict
        ``label``, ``kind``, ``start_s``, ``end_s``, and where known ``axis``, ``up``,
        ``angle_deg``, ``rate_dps``. Sample index ranges are ``[start, end)`` (end exclusive,
        as Python slices and imucal's ``data.iloc[start:end]``): ``start_s = t[start]``,
        ``end_s = t[end - 1]``; time ranges are ``start <= t_s <= end``. A run of one label in
        ``from_column`` is one section (a label repeated in separate runs is an error).

    Raises
    ------
    DeclarationError
        Unknown label (no meaning given), index outside the recording, reversed range.
    RawDataError, FileNotFoundError
        The section file cannot be read.
    """
    meanings = {**FERRARIS_LABELS, **dict(spec.get("labels") or {})}
    if "from_column" in spec:
        ranges = _label_runs(labels, spec["from_column"], where)
        index = "sample_rows"
        source = f"column {spec['from_column']!r}"
    else:
        path = Path(spec["file"])
        if not path.is_file():
            raise FileNotFoundError(f"{where}.file: {path} not found; expected an existing file")
        fmt = spec.get("format", "ferraris_json")
        ranges = _section_json(path) if fmt == "ferraris_json" else _section_csv(path)
        index = spec.get("index", "sample")
        source = str(path)
    out = []
    for row in ranges:
        label = row["label"]
        meaning = {k: row[k] for k in SECTION_CSV_OPTIONAL if row.get(k) not in (None, "")}
        if "kind" not in meaning:
            if label not in meanings:
                raise DeclarationError(
                    f"{where}.labels.{label}",
                    f"label {label!r} of {source} has no meaning",
                    "a labels entry with its kind (x_p .. z_rot of a Ferraris session are known)",
                )
            meaning = {**meanings[label], **meaning}
        start, end = row["start"], row["end"]
        if index == "time":
            start_s, end_s = float(start), float(end)
        else:
            times = t_s if index == "sample_rows" else primary_t_s
            n = times.size
            if not (0 <= start < end <= n):
                raise DeclarationError(
                    f"{where}",
                    f"section {label!r} of {source}: samples {start}..{end} (end exclusive) "
                    f"of a recording with {n}",
                    f"0 <= start < end <= {n}",
                )
            start_s, end_s = float(times[int(start)]), float(times[int(end) - 1])
        if not start_s < end_s:
            raise DeclarationError(
                f"{where}",
                f"section {label!r} of {source}: {start_s} s to {end_s} s",
                "start < end",
            )
        entry = {"label": str(label), "start_s": start_s, "end_s": end_s, **meaning}
        if "angle_deg" in entry:
            entry["angle_deg"] = float(entry["angle_deg"])
        out.append(entry)
    return sorted(out, key=lambda e: e["start_s"])


def _section_json(path: Path) -> list[dict]:
    data = io.read_json(path)
    if not isinstance(data, dict):
        raise io.RawDataError(
            path, None, f"a JSON {type(data).__name__}", '{"label": {"start": ., "end": .}}'
        )
    rows = []
    for label, value in data.items():
        if not (isinstance(value, dict) and {"start", "end"} <= set(value)):
            raise io.RawDataError(
                path, None, f"{label!r}: {value!r}", '{"start": <int>, "end": <int>}'
            )
        rows.append({"label": label, "start": value["start"], "end": value["end"]})
    return rows


def _section_csv(path: Path) -> list[dict]:
    table = pd.read_csv(path, dtype=str, keep_default_na=False, skipinitialspace=True)
    missing = [c for c in ("label", "start", "end") if c not in table.columns]
    if missing:
        raise io.RawDataError(
            path,
            1,
            f"missing column(s) {missing} in {list(table.columns)}",
            "label,start,end[,kind,axis,up,angle_deg,rate_dps]",
        )
    rows = []
    for i, rec in enumerate(table.to_dict("records")):
        try:
            start, end = float(rec["start"]), float(rec["end"])
        except ValueError:
            raise io.RawDataError(
                path, i + 2, f"start {rec['start']!r}, end {rec['end']!r}", "numbers"
            ) from None
        row = {"label": rec["label"], "start": start, "end": end}
        for key in SECTION_CSV_OPTIONAL:
            if rec.get(key, "") != "":
                row[key] = float(rec[key]) if key in ("angle_deg", "rate_dps") else rec[key]
        rows.append(row)
    for row in rows:  # sample indices are integers
        for key in ("start", "end"):
            if float(row[key]).is_integer():
                row[key] = int(row[key])
    return rows


def _label_runs(labels: np.ndarray | None, column: str, where: str) -> list[dict]:
    if labels is None:
        raise DeclarationError(
            f"{where}.from_column", f"column {column!r} not read", "a column of the recording"
        )
    values = np.asarray(labels, dtype=str)
    change = np.flatnonzero(values[1:] != values[:-1]) + 1
    starts = np.concatenate(([0], change))
    ends = np.concatenate((change, [values.size]))
    rows, seen = [], {}
    for a, b in zip(starts, ends):
        label = values[a]
        if label == "":
            continue
        if label in seen:
            raise DeclarationError(
                f"{where}.from_column",
                f"label {label!r} of column {column!r} in two runs (rows {seen[label]} and {a})",
                "each label in one run of rows",
            )
        seen[label] = int(a)
        rows.append({"label": label, "start": int(a), "end": int(b)})
    return rows
