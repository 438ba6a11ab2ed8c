"""Rules blind_score, stress_score, detection_score: unseal the answer keys of a check, score
its diagnoses and write the score and its page (imucal.gap.checks)."""

from pathlib import Path
from typing import TYPE_CHECKING

from imucal.gap.checks import score_check
from imucal.io import write_json
from imucal.io.logs import log_to

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

log_to(snakemake.log[0])
score, page = score_check(
    snakemake.params.check,
    snakemake.input.diagnoses,
    snakemake.input.sealed,
    snakemake.input.benchmarks,
    detection_score=getattr(snakemake.params, "detection_score", None),
    **snakemake.params.options,
)
write_json(score, snakemake.output.score)
Path(snakemake.output.html).write_text(page)
