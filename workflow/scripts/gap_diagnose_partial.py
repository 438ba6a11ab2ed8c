"""Rule gap_diagnose_partial: the gap diagnosis of a partial session (imucal.gap.partialsession)."""

import logging
from pathlib import Path
from typing import TYPE_CHECKING

from imucal.gap import DiagnosisSettings
from imucal.gap.partialsession import diagnose_partial
from imucal.io import read_json, read_recording, read_segments, write_json
from imucal.io.dataset import read_dataset
from imucal.io.logs import log_to
from imucal.plots.figurefile import save_figure
from imucal.report.gapfigures import plot_effects, plot_gap_map

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

log_to(snakemake.log[0])
info = read_dataset(Path(snakemake.input.dataset_yaml).parent)
inputs = dict(snakemake.input.items())
recordings = ("static", "poses")
tables = {
    key: read_recording(path)[0]
    for key, path in inputs.items()
    if key in recordings or key.startswith(("moving_", "rest_"))
}
references = {}
for path in inputs.get("orientation", []):
    table, metadata = read_recording(path)
    references[metadata["recording"]] = (table, metadata)
result = diagnose_partial(
    info,
    tables,
    dataset=snakemake.wildcards.dataset,
    calibration=read_json(snakemake.input.calibration),
    summary=read_json(snakemake.input.summary),
    segments=read_segments(inputs["segments"]) if "segments" in inputs else None,
    references=references,
    settings=DiagnosisSettings.from_config(snakemake.params.settings),
    windows_s=snakemake.params.windows_s,
    poses_recording=snakemake.params.poses_recording,
    settle_s=snakemake.params.settle_s,
)
write_json(result, snakemake.output.diagnosis)
save_figure(plot_gap_map(result), snakemake.output.gap_map)
save_figure(plot_effects(result), snakemake.output.effects)
logging.info("scope %s, explained %s", result["scope"], result["explained"])
