"""Rule gap_diagnose: one session's sim-to-real gap diagnosis (imucal.gap.diagnose)."""

import logging
from typing import TYPE_CHECKING

from imucal.constants import IMU_RECORDINGS
from imucal.gap import diagnose
from imucal.gap.figures import plot_effects, plot_gap_map
from imucal.io import read_recording, read_segments, write_json
from imucal.io.dataset import read_dataset
from imucal.pipeline.full import PipelineOptions

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

logging.basicConfig(filename=snakemake.log[0], filemode="w", level=logging.INFO)
p = snakemake.params
info = read_dataset(p.folder)
imu = {
    r: read_recording(getattr(snakemake.input, r))[0]
    for r in IMU_RECORDINGS
    if r in snakemake.input.keys()
}  # noqa: SIM118
reference = (
    read_recording(snakemake.input.reference)[0] if "reference" in snakemake.input.keys() else None
)  # noqa: SIM118
options = PipelineOptions.of_dataset(
    info,
    exact_rotation=p.exact_rotation,
    lowpass_order=p.lowpass_order,
    lowpass_cutoff_hz=p.lowpass_cutoff_hz,
)
result = diagnose(
    imu, reference, options, dataset=snakemake.wildcards.dataset,
    segments=read_segments(snakemake.input.segments), replicas=p.replicas, alpha=p.alpha,
    seed=p.seed, min_heldout_shrink=p.min_heldout_shrink, crn_seeds=p.crn_seeds,
    detect_z=p.detect_z, exclude=tuple(p.exclude),
)  # fmt: skip
write_json(result, snakemake.output.diagnosis)
plot_gap_map(result).savefig(snakemake.output.gap_map, dpi=110)
plot_effects(result).savefig(snakemake.output.effects, dpi=110)
logging.info("explained %s, remaining %s", result["explained"], result["remaining"]["total"])
