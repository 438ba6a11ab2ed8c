"""The array readers of a declared entry: MATLAB v5 (scipy), MATLAB v7.3 and HDF5 (h5py) and
netCDF4 (CF conventions: packed variables, time units and sensor unit spellings).
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from imucal import io
from imucal.columns import TIME
from imucal.io.readers.declaration import (
    SENSOR_TARGETS,
    DeclarationError,
    is_array_column,
    is_index,
)


def read_arrays(
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
        if not is_index(source):
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
        if not is_array_column(source):
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


def netcdf_time_and_units(
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
        sensor = target.split("_", 1)[0] if target in SENSOR_TARGETS else None
        name = src[0] if is_array_column(src) else src if isinstance(src, str) else None
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
