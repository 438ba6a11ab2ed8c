"""Rule temperature_holdout: the temperature terms held out across the declared static poses."""

from typing import TYPE_CHECKING

from imucal.io import read_recording, read_segments, write_json
from imucal.io.logs import log_to
from imucal.pipeline.outcome import stage_guard
from imucal.terms.poseholdout import hold_out_recording

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

log_to(snakemake.log[0])
p = snakemake.params

with stage_guard("temperature_holdout", snakemake.output):
    table, _ = read_recording(snakemake.input.recording)
    result = hold_out_recording(
        table, read_segments(snakemake.input.segments), recording=p.recording,
        block_s=p.block_s, settle_s=p.settle_s, max_order=p.max_order, margin_c=p.margin_c,
        se_block_s=p.se_block_s,
    )  # fmt: skip
    write_json(result, snakemake.output.holdout)
