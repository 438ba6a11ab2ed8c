from .sheet import SHEET_COLUMNS, read_sample_sheet
from .store import calibration_for, store_index
from .summary import drift_table, flag_outliers, parameter_table, summarize_fleet
