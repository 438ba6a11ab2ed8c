"""Rule gap_checks_summary: the blind, stress and outside-library checks summed up, with the
spread effects named where they were not injected over all their sessions
(imucal.gap.checksummary)."""

from pathlib import Path
from typing import TYPE_CHECKING

from imucal.gap.checksummary import summarize_checks
from imucal.io import write_json
from imucal.io.logs import log_to

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

log_to(snakemake.log[0])
files = {
    check: {
        "diagnoses": snakemake.input[f"{check}_diagnoses"],
        "sealed": snakemake.input[f"{check}_sealed"],
        "score": snakemake.input[f"{check}_score"],
    }
    for check in snakemake.params.checks
}
summary, text = summarize_checks(files)
write_json(summary, snakemake.output.summary)
Path(snakemake.output.text).write_text(text + "\n")
