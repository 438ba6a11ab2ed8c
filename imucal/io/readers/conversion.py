"""The columns of a declared entry in SI units: its time, its integer counters and its sensors
(source unit to SI, counts by their sensitivity, the declared axis permutation and signs).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from imucal import io
from imucal.columns import AXES, SENSOR_COLUMNS, TIME
from imucal.constants import STANDARD_GRAVITY_M_S2
from imucal.io.readers.declaration import DeclarationError

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


def time_values(
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


def integer_values(values: np.ndarray, path: Path, name: str, first_line: int | None) -> np.ndarray:
    bad = np.flatnonzero(~np.isfinite(values) | (values != np.round(values)))
    if bad.size:
        raise io.RawDataError(
            path, _line(first_line, bad[0]), f"{name} is {values[bad[0]]}", "an integer counter"
        )
    return values.astype(np.int64)


def sensor_values(
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
