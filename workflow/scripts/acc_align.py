"""Rule acc_align: accelerometer step 2, T_R,acc from the filtered rotation3d phases."""

import logging
from typing import TYPE_CHECKING

from imucal.io import read_recording, read_segments, write_json
from imucal.pipeline.outcome import read_artifact, stage_guard
from imucal.pipeline.stages import align_acc

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

logging.basicConfig(filename=snakemake.log[0], filemode="w", level=logging.INFO)

with stage_guard("acc_align", snakemake.output):
    rotation3d, _ = read_recording(snakemake.input.rotation3d)
    acc = align_acc(
        rotation3d,
        read_segments(snakemake.input.segments),
        read_artifact(snakemake.input.fit),
        method=snakemake.params.method,
        exact=snakemake.params.exact,
    )
    write_json(acc, snakemake.output.acc)
