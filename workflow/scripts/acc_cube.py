"""Rule acc_cube: accelerometer step 1, the cube fit (eq. 32)."""

import logging
from typing import TYPE_CHECKING

from imucal.io import read_recording, read_segments, write_json
from imucal.pipeline.outcome import stage_guard
from imucal.pipeline.stages import fit_acc_cube

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

logging.basicConfig(filename=snakemake.log[0], filemode="w", level=logging.INFO)

with stage_guard("acc_cube", snakemake.output):
    cube, _ = read_recording(snakemake.input.cube)
    fit, figures = fit_acc_cube(
        cube,
        read_segments(snakemake.input.segments),
        gravity_m_s2=snakemake.params.gravity_m_s2,
        saturation_limit_m_s2=snakemake.params.saturation_limit_m_s2,
        method=snakemake.params.method,
    )
    write_json(fit, snakemake.output.fit)
    figures["acc_cube"].savefig(snakemake.output.figure, dpi=110)
