"""What a recording declaration of ``dataset.yaml`` is: its one-file entries and files, the checks
of its target column names shared by every reader, the error that names the ``dataset.yaml`` key
(:class:`DeclarationError`) and the recording read from it (:class:`DeclaredRecording`).
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from imucal.columns import SENSOR_COLUMNS, SEQ, TIME

#: Reader names of a one-file entry.
READERS = ("table", "matlab", "hdf5", "netcdf")


#: Target names besides ``t_s``, ``seq`` and the sensor columns (kept as they are in the source).
EXTRA_NAME = re.compile(r"^[a-z][a-z0-9_]*$")


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


SENSOR_TARGETS = {c for cols in SENSOR_COLUMNS.values() for c in cols}


def check_targets(columns: Mapping[str, Any], where: str) -> None:
    for target, source in columns.items():
        known = target in (TIME, SEQ) or target in SENSOR_TARGETS or EXTRA_NAME.match(target)
        if not known:
            raise DeclarationError(
                f"{where}.columns.{target}",
                f"target {target!r}",
                "t_s, seq, acc_x..mag_z or an extra name of lower-case letters, digits and _",
            )
        if not (is_index(source) or isinstance(source, str) or is_array_column(source)):
            raise DeclarationError(
                f"{where}.columns.{target}",
                f"source {source!r}",
                "a column name, a 0-based column index or [array, 0-based column index]",
            )


def is_index(source: Any) -> bool:
    return isinstance(source, int) and not isinstance(source, bool) and source >= 0


def is_array_column(source: Any) -> bool:
    """``[array, index]``: a column of a named 2-D array (MATLAB variable, HDF5 dataset)."""
    return (
        isinstance(source, (list, tuple))
        and len(source) == 2
        and isinstance(source[0], str)
        and is_index(source[1])
    )
