"""Rule gyr_table: rate-table fit of the run means (eq. 33, vector form)."""

import logging
from typing import TYPE_CHECKING

from imucal.io import read_recording, read_segments, write_json
from imucal.pipeline.outcome import stage_guard
from imucal.pipeline.stages import fit_gyr_table

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

logging.basicConfig(filename=snakemake.log[0], filemode="w", level=logging.INFO)

with stage_guard("gyr_table", snakemake.output):
    ratetable, _ = read_recording(snakemake.input.ratetable)
    fit, figures = fit_gyr_table(
        ratetable,
        read_segments(snakemake.input.segments),
        saturation_limit_rad_s=snakemake.params.saturation_limit_rad_s,
    )
    write_json(fit, snakemake.output.fit)
    figures["gyr_table"].savefig(snakemake.output.figure, dpi=110)
