"""Many sensors, many sessions: the sample sheet (``sheet``), the parameters of a fleet across
units and over time (``summary``) and the calibration store (``store``)."""

from imucal.fleet.sheet import SHEET_COLUMNS, read_sample_sheet
from imucal.fleet.store import calibration_for, store_index
from imucal.fleet.summary import drift_table, flag_outliers, parameter_table, summarize_fleet

__all__ = [
    "SHEET_COLUMNS",
    "calibration_for",
    "drift_table",
    "flag_outliers",
    "parameter_table",
    "read_sample_sheet",
    "store_index",
    "summarize_fleet",
]
