"""Rule partial: every stage a partial session allows, the skipped ones with their reason."""

import logging
from pathlib import Path
from typing import TYPE_CHECKING

from imucal.calibration import FORMAT_VERSION
from imucal.ingest import sensor_limits
from imucal.io import read_recording, read_segments, write_json
from imucal.io.dataset import read_dataset
from imucal.io.logs import log_to
from imucal.pipeline import partial
from imucal.pipeline.options import FitMethods
from imucal.plots.figurefile import save_figure

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

log_to(snakemake.log[0])
settings = snakemake.params.pipeline
methods = FitMethods.of(settings["methods"])

dataset = read_dataset(Path(snakemake.input.dataset_yaml).parent)
names = [n for n in dataset.recordings if n != "reference"]
ingested = {name: read_recording(snakemake.input[name]) for name in names}
tables = {name: table for name, (table, _) in ingested.items()}
# readings at a sensor's range are clipped: the fits leave them out where the range is known
limits = sensor_limits((meta for _, meta in ingested.values()), dataset.range_counts)
_, segment_meta = read_recording(snakemake.input.segments)
references = {}
for path in snakemake.input.orientation:
    reference, metadata = read_recording(path)
    references[metadata["recording"]] = (reference, metadata)
outcomes = partial.run_stages(
    tables,
    read_segments(snakemake.input.segments),
    notes=segment_meta.get("notes", {}),
    lowpass_order=settings["lowpass_order"],
    lowpass_cutoff_hz=settings["lowpass_cutoff_hz"],
    gravity_m_s2=dataset.gravity_m_s2,
    field_norm=dataset.field_norm,
    ratetable=dataset.ratetable,
    saturation_m_s2=limits.get("acc"),
    saturation_rad_s=limits.get("gyr"),
    references=references,
    reference_where={name: dataset.reference_where(name) for name in references},
    methods=methods,
    exact_rotation=settings["exact_rotation"],
)
for o in outcomes:
    logging.info("%-22s %-8s %s", o.name, o.status, o.reason)
final = partial.final_calibration(outcomes, methods, settings["exact_rotation"])
calibration = {
    "format_version": FORMAT_VERSION,
    **{sensor: entry["calibration"] for sensor, entry in final["sensors"].items()},
    "missing": final["missing"],
    "frame": "B of the session's own protocol (see each sensor's method)",
}
write_json(calibration, snakemake.output.calibration)
write_json(
    {"dataset": dataset.name, "stages": [o.summary() for o in outcomes]}, snakemake.output.stages
)
for sensor, artifacts in partial.stage_results(outcomes).items():
    write_json(artifacts, snakemake.output[sensor])
figure_dir = Path(snakemake.output.figures)
figure_dir.mkdir(parents=True, exist_ok=True)
for name, figure in partial.figures(outcomes, tables).items():
    save_figure(figure, figure_dir / f"{name}.png")
