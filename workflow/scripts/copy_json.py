"""Rule stages: publish the stage listing of the path the session took."""

import logging
from typing import TYPE_CHECKING

from imucal.io import read_json, write_json

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

logging.basicConfig(filename=snakemake.log[0], filemode="w", level=logging.INFO)
write_json(read_json(snakemake.input.stages), snakemake.output.stages)
