from .metrics import (
    NO_REFERENCE_NOTE,
    angles_deg,
    compare_vectors,
    summarise_dip,
    validate,
)
from .mounting import (
    MOUNTING_CONVENTION,
    Mounting,
    estimate_mounting,
)
from .timing import (
    TIME_CONVENTION,
    TimeAlignment,
    align_reference,
    correlate_offsets,
    estimate_time_alignment,
    packet_times,
)
