"""Rule mag_step1: magnetometer ellipsoid fit (eqs. 17-24) with optional LM refinement."""

import logging
from typing import TYPE_CHECKING

from imucal.io import read_recording, write_json
from imucal.pipeline.outcome import stage_guard
from imucal.pipeline.stages import fit_mag_step1

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

logging.basicConfig(filename=snakemake.log[0], filemode="w", level=logging.INFO)

with stage_guard("mag_step1", snakemake.output):
    cube = read_recording(snakemake.input.cube)[0] if "cube" in snakemake.input.keys() else None
    step1 = fit_mag_step1(
        read_recording(snakemake.input.rotation3d)[0],
        cube,
        field_norm=snakemake.params.field_norm,
        refine_lm=snakemake.params.refine_lm,
    )
    write_json(step1, snakemake.output.step1)
