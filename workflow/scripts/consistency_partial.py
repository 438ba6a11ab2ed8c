"""Rule consistency_partial: a partial session's calibration refitted on independent parts."""

import logging
from pathlib import Path
from typing import TYPE_CHECKING

from imucal.io import read_json, read_recording, read_segments, write_json
from imucal.io.dataset import read_dataset
from imucal.pipeline.partial import session_of
from imucal.pipeline.parts import check_partial_session

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

logging.basicConfig(filename=snakemake.log[0], filemode="w", level=logging.INFO)
dataset = read_dataset(Path(snakemake.input.dataset_yaml).parent)
names = [n for n in dataset.recordings if n != "reference"]
_, segment_meta = read_recording(snakemake.input.segments)
references = {}
for path in snakemake.input.orientation:
    reference, metadata = read_recording(path)
    references[metadata["recording"]] = (reference, metadata)
session = session_of(
    dataset,
    {name: read_recording(snakemake.input[name]) for name in names},
    read_segments(snakemake.input.segments),
    segment_meta.get("notes", {}),
    references,
    snakemake.params.pipeline,
)
check = check_partial_session(
    session,
    read_json(snakemake.input.listing)["stages"],
    read_json(snakemake.input.calibration),
    {k: v for s in ("mag", "acc", "gyr") for k, v in read_json(snakemake.input[s]).items()},
)
write_json(check, snakemake.output.check)
for sensor, entry in check["sensors"].items():
    logging.info("%s %s: inflation %s", sensor, entry["stage"], entry["inflation"])
