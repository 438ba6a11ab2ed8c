"""What the stage functions share: the JSON-ready copy of an artifact, the saturation test, the
phases of a rotation3d recording and the sensors a recording holds.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np
import pandas as pd

from imucal.columns import ACC, GYR, MAG
from imucal.fits.alignment import phase_samples

ALIGNMENT_METHODS = ("full", "paper")


def plain(obj):
    """JSON-ready copy of a dataclass / dict / array tree."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: plain(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, Mapping):
        return {str(k): plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [plain(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    return obj


def at_range(values: np.ndarray, limit: float) -> np.ndarray:
    """Rows of ``values`` (n, 3) with any axis at or beyond the sensor range ``limit`` (clipped
    readings)."""
    return np.any(np.abs(values) >= limit, axis=1)


def phase_values(table: pd.DataFrame, segments: pd.DataFrame, sensor: str) -> dict[str, np.ndarray]:
    """Phase label -> the sensor's samples (n, 3) in that rotation3d phase."""
    return {label: values for label, (_, values) in phase_samples(table, segments, sensor).items()}


def sensors_of(table: pd.DataFrame) -> tuple[str, ...]:
    """Sensors with at least one finite sample in an ingested table."""
    present = []
    for sensor, columns in (("acc", ACC), ("gyr", GYR), ("mag", MAG)):
        if (
            all(c in table.columns for c in columns)
            and np.isfinite(table[list(columns)].to_numpy(dtype=float)).all(axis=1).any()
        ):
            present.append(sensor)
    return tuple(present)
