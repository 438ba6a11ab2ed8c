"""Rule gyr: the gyroscope calibration with and without tools, and Tables I and II."""

import logging
from typing import TYPE_CHECKING

from imucal.io import read_json, write_json
from imucal.stages import combine_gyr

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

logging.basicConfig(filename=snakemake.log[0], filemode="w", level=logging.INFO)

optional = {
    key: read_json(snakemake.input[key]) if key in snakemake.input.keys() else None
    for key in ("table", "table_alignment", "truth")
}
gyr, tables = combine_gyr(
    read_json(snakemake.input.bias),
    read_json(snakemake.input.alignment),
    read_json(snakemake.input.scale),
    optional["table"],
    optional["table_alignment"],
    bias_estimator=snakemake.params.bias_estimator,
    exact=snakemake.params.exact,
    truth=optional["truth"],
)
write_json(gyr, snakemake.output.gyr)
tables.to_csv(snakemake.output.tables, index=False)
