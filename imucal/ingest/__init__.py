"""Ingest: raw logs to SI-unit tables (``recording``), the checks of their content carried over
batches (``checks``), the summary (``summary``), the packet counter and receive timestamps
(``timebase``).
"""

from imucal.ingest.checks import CountRange, LogChecks, check_count_range, check_log
from imucal.ingest.recording import (
    REF_TICK_MODULUS,
    counts_to_si,
    ingest_recording,
    ingest_to_parquet,
    reference_to_table,
)
from imucal.ingest.summary import MAX_LISTED_GAPS, summarize_dataset, summarize_recording

__all__ = [
    "MAX_LISTED_GAPS",
    "REF_TICK_MODULUS",
    "CountRange",
    "LogChecks",
    "check_count_range",
    "check_log",
    "counts_to_si",
    "ingest_recording",
    "ingest_to_parquet",
    "reference_to_table",
    "summarize_dataset",
    "summarize_recording",
]
