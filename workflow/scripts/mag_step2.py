"""Rule mag_step2: T_R,mag from the rotation3d phases (eqs. 25-27), paper and full-phase."""

import logging
from typing import TYPE_CHECKING

from imucal.io import read_recording, read_segments, write_json
from imucal.pipeline.outcome import read_artifact, stage_guard
from imucal.pipeline.stages import align_mag
from imucal.plots.magnetometer import plot_magnetometer_steps

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

logging.basicConfig(filename=snakemake.log[0], filemode="w", level=logging.INFO)

with stage_guard("mag_step2", snakemake.output):
    rotation3d, _ = read_recording(snakemake.input.rotation3d)
    segments = read_segments(snakemake.input.segments)
    mag = align_mag(
        rotation3d,
        segments,
        read_artifact(snakemake.input.step1),
        method=snakemake.params.method,
        exact=snakemake.params.exact,
    )
    write_json(mag, snakemake.output.mag)
    for name, figure in plot_magnetometer_steps(rotation3d, segments, mag).items():
        figure.savefig(snakemake.output[name], dpi=110)
