"""Rule validate: the calibration checked against the reference (or reference-free checks)."""

from typing import TYPE_CHECKING

from imucal.io import read_calibration, read_recording, read_segments, write_json
from imucal.io.logs import log_to
from imucal.pipeline.outcome import stage_guard
from imucal.pipeline.stages import validate_session

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

log_to(snakemake.log[0])

with stage_guard("validate", snakemake.output):
    rotation3d, metadata = read_recording(snakemake.input.rotation3d)
    has_reference = "reference" in snakemake.input.keys()
    reference = read_recording(snakemake.input.reference)[0] if has_reference else None
    result = validate_session(
        rotation3d,
        metadata,
        reference,
        read_segments(snakemake.input.segments),
        read_calibration(snakemake.input.calibration),
    )
    write_json(result, snakemake.output.validation)
