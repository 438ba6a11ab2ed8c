"""Rule gyr: the gyroscope calibration with and without tools, and Tables I and II."""

import logging
from typing import TYPE_CHECKING

from imucal.io import write_json
from imucal.pipeline.outcome import read_artifact, read_optional_artifact, stage_guard
from imucal.pipeline.stages import combine_gyr

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

logging.basicConfig(filename=snakemake.log[0], filemode="w", level=logging.INFO)

with stage_guard("gyr", snakemake.output):
    # the rate table's stages may not have run (the tool-free result is used then); with them,
    # the tool-free scale (eq. 36) is not needed and may not have run
    optional = {
        key: read_optional_artifact(snakemake.input[key]) if key in snakemake.input.keys() else None
        for key in ("table", "table_alignment", "truth")
    }
    with_table = optional["table"] and optional["table_alignment"]
    read_scale = read_optional_artifact if with_table else read_artifact
    gyr, tables = combine_gyr(
        read_artifact(snakemake.input.bias),
        read_scale(snakemake.input.scale),
        optional["table"],
        optional["table_alignment"],
        bias_estimator=snakemake.params.bias_estimator,
        exact=snakemake.params.exact,
        truth=optional["truth"],
    )
    write_json(gyr, snakemake.output.gyr)
    tables.to_csv(snakemake.output.tables, index=False)
