"""Rule calibration_partial: the calibration a partial session ships, its standard deviations
inflated where its parts disagree beyond them (imucal.validation.consistency.ship)."""

import logging
from typing import TYPE_CHECKING

from imucal.io import read_json, write_json
from imucal.validation.consistency import ship

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

logging.basicConfig(filename=snakemake.log[0], filemode="w", level=logging.INFO)
calibration = ship(read_json(snakemake.input.calibration), read_json(snakemake.input.check))
write_json(calibration, snakemake.output.calibration)
