"""Rule calibration: calibration.json of all three sensors in frame B."""

import logging
from typing import TYPE_CHECKING

from imucal.io import read_json, write_calibration
from imucal.stages import combine_calibration

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

logging.basicConfig(filename=snakemake.log[0], filemode="w", level=logging.INFO)

calibration = combine_calibration(
    read_json(snakemake.input.acc), read_json(snakemake.input.gyr), read_json(snakemake.input.mag)
)
write_calibration(calibration, snakemake.output.calibration)
