"""Files and readers: the raw logs, the declared readers of ``dataset.yaml``, parquet and JSON.

``raw`` reads the native IMU CSV log and the MT Manager export; ``readers`` the declared
formats (tables, MATLAB, HDF5, streams); ``dataset`` the ``dataset.yaml`` declaration; ``store``
what the pipeline writes and reads back; ``logs`` the rules' log files. Only this layer touches
files.
"""

from imucal.io.logs import LOG_FORMAT, LoggedWarning, log_to, read_log_warnings
from imucal.io.raw import (
    BATCH_BYTES,
    IMU_CSV_FORMAT,
    MT_MANAGER_FORMAT,
    ImuCsvStream,
    MtManagerExport,
    RawDataError,
    read_imu_csv,
    read_mt_manager_export,
)
from imucal.io.store import (
    METADATA_KEY,
    RecordingWriter,
    read_benchmark_seconds,
    read_calibration,
    read_json,
    read_recording,
    read_recording_batches,
    read_recording_column,
    read_segments,
    recording_column_names,
    sha256_file,
    to_jsonable,
    write_calibration,
    write_json,
    write_recording,
    write_table,
)

__all__ = [
    "BATCH_BYTES",
    "IMU_CSV_FORMAT",
    "LOG_FORMAT",
    "LoggedWarning",
    "ImuCsvStream",
    "METADATA_KEY",
    "MT_MANAGER_FORMAT",
    "MtManagerExport",
    "RawDataError",
    "RecordingWriter",
    "read_benchmark_seconds",
    "read_calibration",
    "read_imu_csv",
    "log_to",
    "read_json",
    "read_log_warnings",
    "read_mt_manager_export",
    "read_recording",
    "read_recording_batches",
    "read_recording_column",
    "recording_column_names",
    "read_segments",
    "to_jsonable",
    "sha256_file",
    "write_calibration",
    "write_json",
    "write_recording",
    "write_table",
]
