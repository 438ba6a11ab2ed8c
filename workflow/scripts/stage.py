"""Every stage rule of the paper's protocol: runs the job's stages in order (imucal.pipeline.jobs)
and writes each one's artifact and figures, or their not-run forms when the data do not allow
the stage."""

from typing import TYPE_CHECKING

from imucal.io.logs import log_to
from imucal.pipeline.jobs import STAGE_JOBS, run_job

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

log_to(snakemake.log[0])
run_job(
    STAGE_JOBS[snakemake.rule],
    sources=dict(snakemake.input.items()),
    outputs=dict(snakemake.output.items()),
    settings=snakemake.params.settings,
    recordings=frozenset(snakemake.params.recordings),
)
