"""Validation against a reference IMU: time base (``timing``), mounting (``mounting``) and the
metrics before and after calibration (``metrics``).
"""

from imucal.validation.timing import (
    TIME_CONVENTION,
    unwrap_seq,
    packet_times,
    TimeAlignment,
    estimate_time_alignment,
    correlate_offsets,
    align_reference,
)
from imucal.validation.mounting import (
    MOUNTING_CONVENTION,
    Mounting,
    estimate_mounting,
)
from imucal.validation.metrics import (
    NO_REFERENCE_NOTE,
    angles_deg,
    compare_vectors,
    summarise_dip,
    validate,
)

__all__ = [
    "MOUNTING_CONVENTION",
    "Mounting",
    "NO_REFERENCE_NOTE",
    "TIME_CONVENTION",
    "TimeAlignment",
    "align_reference",
    "angles_deg",
    "compare_vectors",
    "correlate_offsets",
    "estimate_mounting",
    "estimate_time_alignment",
    "packet_times",
    "summarise_dip",
    "unwrap_seq",
    "validate",
]
