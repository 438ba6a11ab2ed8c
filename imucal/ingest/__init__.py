"""Ingest: raw logs to SI-unit tables with their checks and summary (``recording``), the packet
counter and receive timestamps (``timebase``), declared orientation references (``orientation``).
"""

from imucal.ingest.orientation import ingest_orientation_reference
from imucal.ingest.recording import (
    MAX_LISTED_GAPS,
    REF_TICK_MODULUS,
    check_log,
    counts_to_si,
    ingest_recording,
    reference_to_table,
    summarize_dataset,
    summarize_recording,
)

__all__ = [
    "MAX_LISTED_GAPS",
    "REF_TICK_MODULUS",
    "check_log",
    "counts_to_si",
    "ingest_orientation_reference",
    "ingest_recording",
    "reference_to_table",
    "summarize_dataset",
    "summarize_recording",
]
