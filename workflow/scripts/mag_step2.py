"""Rule mag_step2: T_R,mag from the rotation3d phases (eqs. 25-27), paper and full-phase."""

import logging
from typing import TYPE_CHECKING

from imucal.io import read_json, read_recording, write_json, read_segments
from imucal.stages import align_mag

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

logging.basicConfig(filename=snakemake.log[0], filemode="w", level=logging.INFO)

mag = align_mag(
    read_recording(snakemake.input.rotation3d)[0],
    read_segments(snakemake.input.segments),
    read_json(snakemake.input.step1),
    method=snakemake.params.method,
    exact=snakemake.params.exact,
)
write_json(mag, snakemake.output.mag)
