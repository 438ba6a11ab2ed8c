"""Rule blind_score: unseal the answer keys and score the blind diagnoses (+ report page)."""

import logging
from pathlib import Path
from typing import TYPE_CHECKING

from imucal.gap.blind import score_blind
from imucal.gap.figures import render_blind_page
from imucal.io import read_benchmark_seconds, read_json, write_json

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

logging.basicConfig(filename=snakemake.log[0], filemode="w", level=logging.INFO)
name = lambda path: Path(path).stem
diagnoses = {name(f): read_json(f) for f in snakemake.input.diagnoses}
keys = {name(f): read_json(f) for f in snakemake.input.sealed}
score = score_blind(diagnoses, keys)
score["diagnosis_seconds"] = read_benchmark_seconds(snakemake.input.benchmarks)
write_json(score, snakemake.output.score)
Path(snakemake.output.html).write_text(render_blind_page(score))
