"""Column names and units of the ingested tables, defined once.

Every table the pipeline writes (ingested recordings, low-pass filtered recordings) uses these
names. Sensor values are in SI units after ingest: the accelerometer in m/s^2 (specific force),
the gyroscope in rad/s, the magnetometer normalised to the field norm of the dataset.
"""

from __future__ import annotations

import numpy as np

TIME = "t_s"
SEQ = "seq"

SENSORS = ("acc", "gyr", "mag")
AXES = ("x", "y", "z")

ACC = ("acc_x", "acc_y", "acc_z")
GYR = ("gyr_x", "gyr_y", "gyr_z")
MAG = ("mag_x", "mag_y", "mag_z")

SENSOR_COLUMNS = {"acc": ACC, "gyr": GYR, "mag": MAG}
#: Standard deviation of a calibrated value from the calibration's parameter covariance
#: (``imucal apply --parameter-std``): the column's name with this suffix, same unit.
PARAMETER_STD_SUFFIX = "_param_std"

#: Header of the native raw CSV format, in this order (extra columns may follow).
RAW_COLUMNS = (TIME, SEQ, *ACC, *GYR, *MAG)

#: Ingested orientation reference: unit quaternion, scalar first, rotating vectors from the
#: reference's body frame to its world frame (``docs/data-format.md``).
QUAT = ("q_w", "q_x", "q_y", "q_z")
#: Declared source columns of an orientation reference: the four quaternion components in the
#: file's order (``scalar`` says where w is), or the rotation matrix row by row.
QUAT_SOURCE = ("q_0", "q_1", "q_2", "q_3")
MATRIX_SOURCE = tuple(f"r_{i}{j}" for i in (1, 2, 3) for j in (1, 2, 3))
#: Optional position of an orientation reference's body in its world frame (m), declared and
#: ingested under the same names (``docs/data-format.md``).
POSITION = ("p_x", "p_y", "p_z")

#: Column of the temperature channel (deg C) when a recording has one, in order of preference.
TEMPERATURE_COLUMNS = ("temp_c", "temperature_c", "temp")

#: Unit of each sensor after ingest (inside the package everything is SI).
SI_UNITS = {"acc": "m/s^2", "gyr": "rad/s", "mag": "normalised"}
#: The unit of every sensor column in SI (the ``units`` of ingested, uncalibrated metadata).
SI_COLUMN_UNITS = {c: SI_UNITS[s] for s in SENSORS for c in SENSOR_COLUMNS[s]}

#: The packet counter is 16 bit and wraps at this value.
SEQ_MODULUS = 65536

# Xsens MT Manager export columns of the reference.
REF_COUNTER = "PacketCounter"
REF_TIME_FINE = "SampleTimeFine"
REF_ACC = ("Acc_X", "Acc_Y", "Acc_Z")
REF_GYR = ("Gyr_X", "Gyr_Y", "Gyr_Z")
REF_MAG = ("Mag_X", "Mag_Y", "Mag_Z")
#: SampleTimeFine counts ticks of this frequency.
REF_TICKS_PER_S = 10_000


def sensor_columns(sensor: str) -> tuple[str, str, str]:
    """Return the three column names of ``sensor`` ('acc', 'gyr' or 'mag')."""
    try:
        return SENSOR_COLUMNS[sensor]
    except KeyError:
        raise ValueError(f"unknown sensor {sensor!r}; expected one of {SENSORS}") from None


def column_values(table, columns, rows: slice = slice(None)) -> np.ndarray:
    """Float values of ``columns`` in ``rows`` of ``table`` (a DataFrame), shape (n, k).

    The array ``table.iloc[rows][list(columns)].to_numpy(dtype=float)``, also in its memory
    order (column after column), read column by column: pandas builds a frame for a selection
    of several columns first, about ten times slower, which adds up in the diagnosis's replicas.
    """
    return np.array([table[c].to_numpy(dtype=float)[rows] for c in columns]).T


def temperature_column(table) -> str | None:
    """The temperature column of ``table`` (a DataFrame), or None when it has none."""
    return next((c for c in TEMPERATURE_COLUMNS if c in table.columns), None)


#: Columns of the segments table (``results/{dataset}/segments.parquet``), in order
#: (docs/architecture.md).
SEGMENT_COLUMNS = (
    "recording", "label", "kind", "start_s", "end_s", "start_index", "end_index",
    "axis", "rate_dps", "sense", "turns", "up", "angle_deg",
)  # fmt: skip
#: Kinds of segment.
KINDS = ("static", "phase", "transition", "position", "run")
#: Kinds of segment at rest in one orientation (a static pose).
POSE_KINDS = ("position", "static")


def row_bounds(rows) -> zip:
    """``(start_index, end_index)`` of each row of a segments table (DataFrame), end exclusive,
    as integers.

    Read from the two columns: iterating the rows (``itertuples``) reads every column,
    its string ones element by element."""
    return zip(rows["start_index"].to_numpy(int), rows["end_index"].to_numpy(int), strict=True)
