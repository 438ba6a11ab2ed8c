"""Rule gap_diagnose: one session's sim-to-real gap diagnosis (imucal.gap.diagnose)."""

import logging
from pathlib import Path
from typing import TYPE_CHECKING

from imucal.constants import IMU_RECORDINGS
from imucal.gap import DiagnosisSettings, diagnose
from imucal.gap.blocks import read_decimated_static
from imucal.io import read_recording, read_segments, write_json
from imucal.io.dataset import read_dataset
from imucal.io.logs import log_to
from imucal.pipeline.full import PipelineOptions
from imucal.plots.figurefile import save_figure
from imucal.report.gapfigures import plot_effects, plot_gap_map

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

log_to(snakemake.log[0])
p = snakemake.params
recordings = dict(snakemake.input.items())
imu = {
    r: read_recording(recordings[r])[0] for r in IMU_RECORDINGS if r in recordings and r != "static"
}
# a long static recording is read batch by batch into its window and block means
blocks = None
if "static" in recordings:
    imu["static"], blocks = read_decimated_static(recordings["static"])
reference = read_recording(recordings["reference"])[0] if "reference" in recordings else None
info = read_dataset(Path(snakemake.input.dataset_yaml).parent)
result = diagnose(
    imu,
    reference,
    PipelineOptions.of_dataset(info, **p.pipeline),
    dataset=snakemake.wildcards.dataset,
    segments=read_segments(snakemake.input.segments),
    settings=DiagnosisSettings.from_config(p.settings),
    static_blocks=blocks,
)
write_json(result, snakemake.output.diagnosis)
save_figure(plot_gap_map(result), snakemake.output.gap_map)
save_figure(plot_effects(result), snakemake.output.effects)
logging.info("explained %s, remaining %s", result["explained"], result["remaining"]["total"])
