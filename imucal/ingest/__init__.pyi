from .checks import CountRange, LogChecks, check_count_range, check_log, sensor_limits
from .orientation import ingest_orientation_reference
from .recording import (
    REF_TICK_MODULUS,
    counts_to_si,
    ingest_recording,
    ingest_to_parquet,
    reference_to_table,
)
from .summary import MAX_LISTED_GAPS, summarize_dataset, summarize_recording
