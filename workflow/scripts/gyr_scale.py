"""Rule gyr_scale: gyroscope scale without tools (eq. 36) after the alignment, and T_R,gyr
refitted at that scale."""

import logging
from typing import TYPE_CHECKING

from imucal.io import read_recording, read_segments, write_json
from imucal.pipeline.outcome import read_artifact, stage_guard
from imucal.pipeline.stages import estimate_gyr_scale

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

logging.basicConfig(filename=snakemake.log[0], filemode="w", level=logging.INFO)

with stage_guard("gyr_scale", snakemake.output):
    rotation3d, _ = read_recording(snakemake.input.rotation3d)
    lowpass, _ = read_recording(snakemake.input.lowpass)
    scale = estimate_gyr_scale(
        rotation3d,
        lowpass,
        read_segments(snakemake.input.segments),
        read_artifact(snakemake.input.bias),
        read_artifact(snakemake.input.alignment),
        read_artifact(snakemake.input.acc),
        read_artifact(snakemake.input.mag),
        bias_estimator=snakemake.params.bias_estimator,
    )
    write_json(scale, snakemake.output.scale)
