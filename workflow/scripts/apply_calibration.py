"""Rule apply_calibration: an ingested recording calibrated to frame B."""

from typing import TYPE_CHECKING

from imucal.io import read_calibration, read_recording, write_recording
from imucal.io.logs import log_to
from imucal.pipeline.stages import apply_calibration

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

log_to(snakemake.log[0])

table, metadata = read_recording(snakemake.input.table)
calibrated, metadata = apply_calibration(
    table, metadata, read_calibration(snakemake.input.calibration)
)
write_recording(calibrated, snakemake.output.table, metadata)
