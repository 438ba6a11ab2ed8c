"""Rule partial: every stage a partial session allows, the skipped ones with their reason."""

import logging
from pathlib import Path
from typing import TYPE_CHECKING

from imucal.io import read_json, read_recording, read_segments, write_json
from imucal.io.dataset import read_dataset
from imucal.io.logs import log_to
from imucal.pipeline import partial
from imucal.plots.figurefile import save_figure
from imucal.terms.thermalship import with_shipped_terms

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

log_to(snakemake.log[0])
dataset = read_dataset(Path(snakemake.input.dataset_yaml).parent)
names = [n for n in dataset.recordings if n != "reference"]
_, segment_meta = read_recording(snakemake.input.segments)
references = {}
for path in snakemake.input.orientation:
    reference, metadata = read_recording(path)
    references[metadata["recording"]] = (reference, metadata)
session = partial.session_of(
    dataset,
    {name: read_recording(snakemake.input[name]) for name in names},
    read_segments(snakemake.input.segments),
    segment_meta.get("notes", {}),
    references,
    snakemake.params.pipeline,
)
files = partial.calibrate_partial(session, dataset.name)
for o in files.outcomes:
    logging.info("%-22s %-8s %s", o.name, o.status, o.reason)
calibration = files.calibration
if "temperature_holdout" in snakemake.input.keys():
    calibration = with_shipped_terms(calibration, read_json(snakemake.input.temperature_holdout))
write_json(calibration, snakemake.output.calibration)
write_json(files.stages, snakemake.output.stages)
for sensor, artifacts in files.artifacts.items():
    write_json(artifacts, snakemake.output[sensor])
figure_dir = Path(snakemake.output.figures)
figure_dir.mkdir(parents=True, exist_ok=True)
for name, figure in partial.figures(files.outcomes, session.recordings).items():
    save_figure(figure, figure_dir / f"{name}.png")
