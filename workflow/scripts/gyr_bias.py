"""Rule gyr_bias: gyroscope bias, LS slope of the cumulative sum (eqs. 34-35) and mean."""

import logging
from typing import TYPE_CHECKING

from imucal.io import read_recording, read_segments, write_json
from imucal.pipeline.outcome import stage_guard
from imucal.pipeline.stages import estimate_gyr_bias

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

logging.basicConfig(filename=snakemake.log[0], filemode="w", level=logging.INFO)

with stage_guard("gyr_bias", snakemake.output):
    tables = {
        name: read_recording(path)[0]
        for name, path in snakemake.input.items()
        if name in ("static", "rotation3d", "cube")
    }
    bias, figures = estimate_gyr_bias(tables, read_segments(snakemake.input.segments))
    write_json(bias, snakemake.output.bias)
    figures["gyr_bias"].savefig(snakemake.output.figure, dpi=110)
