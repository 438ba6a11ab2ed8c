"""Rule apply_calibration: an ingested recording calibrated to frame B."""

import logging
from typing import TYPE_CHECKING

from imucal.io import read_calibration, read_recording, write_recording
from imucal.pipeline.stages import apply_calibration

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

logging.basicConfig(filename=snakemake.log[0], filemode="w", level=logging.INFO)

table, metadata = read_recording(snakemake.input.table)
calibrated, metadata = apply_calibration(
    table, metadata, read_calibration(snakemake.input.calibration)
)
write_recording(calibrated, snakemake.output.table, metadata)
