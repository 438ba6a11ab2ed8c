"""Rule consistency_full: the paper's calibration refitted on independent parts."""

import logging
from pathlib import Path
from typing import TYPE_CHECKING

from imucal.io import read_recording, read_segments, write_json
from imucal.io.dataset import read_dataset
from imucal.pipeline.options import PipelineOptions
from imucal.pipeline.parts import check_full_session

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

logging.basicConfig(filename=snakemake.log[0], filemode="w", level=logging.INFO)
recordings = dict(snakemake.input.items())
names = [n for n in recordings if n not in ("segments", "dataset_yaml")]
check = check_full_session(
    {name: read_recording(recordings[name])[0] for name in names},
    read_segments(snakemake.input.segments),
    PipelineOptions.of_dataset(
        read_dataset(Path(snakemake.input.dataset_yaml).parent), **snakemake.params.pipeline
    ),
)
write_json(check, snakemake.output.check)
for sensor, entry in check["sensors"].items():
    logging.info("%s %s: inflation %s", sensor, entry["stage"], entry["inflation"])
