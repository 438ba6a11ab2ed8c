"""Rule stages_full: the stage listing of a session run by the stage-per-rule workflow."""

import logging
from pathlib import Path
from typing import TYPE_CHECKING

from imucal.dataset import read_dataset
from imucal.io import write_json
from imucal.partial import full_protocol_stages

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

logging.basicConfig(filename=snakemake.log[0], filemode="w", level=logging.INFO)
dataset = read_dataset(Path(snakemake.input.dataset_yaml).parent)
stages = full_protocol_stages(set(dataset.recordings), has_reference=dataset.has("reference"))
write_json({"dataset": dataset.name, "stages": stages}, snakemake.output.stages)
