"""Rule stress_score: unseal the answer keys and score the stress diagnoses (+ report page)."""

import logging
from pathlib import Path
from typing import TYPE_CHECKING

from imucal.gap.stress import render_stress_page, score_stress
from imucal.io import read_benchmark_seconds, read_json, write_json

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

logging.basicConfig(filename=snakemake.log[0], filemode="w", level=logging.INFO)
name = lambda path: Path(path).stem
diagnoses = {name(f): read_json(f) for f in snakemake.input.diagnoses}
keys = {name(f): read_json(f) for f in snakemake.input.sealed}
score = score_stress(diagnoses, keys)
score["diagnosis_seconds"] = read_benchmark_seconds(snakemake.input.benchmarks)
write_json(score, snakemake.output.score)
Path(snakemake.output.html).write_text(render_stress_page(score))
