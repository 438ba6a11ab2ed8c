"""Rule gyr_table_align: T_R,gyr for the rate-table S'_gyr from the rotation3d phases."""

import logging
from typing import TYPE_CHECKING

from imucal.io import read_recording, read_segments, write_json
from imucal.pipeline.outcome import read_artifact, stage_guard
from imucal.pipeline.stages import align_gyr

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

logging.basicConfig(filename=snakemake.log[0], filemode="w", level=logging.INFO)

with stage_guard("gyr_table_align", snakemake.output):
    rotation3d, _ = read_recording(snakemake.input.rotation3d)
    fit = read_artifact(snakemake.input.fit)
    alignment = align_gyr(
        rotation3d,
        read_segments(snakemake.input.segments),
        fit["bias"],
        fit["upper"],
        method=snakemake.params.method,
        exact=snakemake.params.exact,
    )
    write_json(alignment, snakemake.output.alignment)
