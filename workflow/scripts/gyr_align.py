"""Rule gyr_align: T_R,gyr from the filtered rotation3d phases (eqs. 28-31), tool-free path."""

import logging
from typing import TYPE_CHECKING

from imucal.io import read_recording, read_segments, write_json
from imucal.pipeline.outcome import read_artifact, stage_guard
from imucal.pipeline.stages import align_gyr, gyr_bias_value

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

logging.basicConfig(filename=snakemake.log[0], filemode="w", level=logging.INFO)

with stage_guard("gyr_align", snakemake.output):
    rotation3d, _ = read_recording(snakemake.input.rotation3d)
    bias, _ = gyr_bias_value(read_artifact(snakemake.input.bias), snakemake.params.bias_estimator)
    alignment = align_gyr(
        rotation3d,
        read_segments(snakemake.input.segments),
        bias,
        method=snakemake.params.method,
        exact=snakemake.params.exact,
    )
    write_json(alignment, snakemake.output.alignment)
