"""Validation against a reference IMU: time base (``timing``), mounting (``mounting``) and the
metrics before and after calibration (``metrics``).
"""

from imucal.validation.metrics import (
    NO_REFERENCE_NOTE,
    angles_deg,
    compare_vectors,
    summarise_dip,
    validate,
)
from imucal.validation.mounting import (
    MOUNTING_CONVENTION,
    Mounting,
    estimate_mounting,
)
from imucal.validation.timing import (
    TIME_CONVENTION,
    TimeAlignment,
    align_reference,
    correlate_offsets,
    estimate_time_alignment,
    packet_times,
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
    "validate",
]
