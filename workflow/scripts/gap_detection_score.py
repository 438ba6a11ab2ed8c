"""Rule detection_score: unseal the answer keys, score the detection limits (+ report page)."""

import logging
from pathlib import Path
from typing import TYPE_CHECKING

from imucal.gap.detection import score_detection
from imucal.gap.figures import render_detection_page
from imucal.io import read_benchmark_seconds, read_json, write_json

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

logging.basicConfig(filename=snakemake.log[0], filemode="w", level=logging.INFO)
p = snakemake.params
diagnoses = {Path(f).stem: read_json(f) for f in snakemake.input.diagnoses}
keys = {Path(f).stem: read_json(f) for f in snakemake.input.sealed}
score = score_detection(diagnoses, keys, rate=p.rate, confidence=p.confidence)
score["diagnosis_seconds"] = read_benchmark_seconds(snakemake.input.benchmarks)
write_json(score, snakemake.output.score)
Path(snakemake.output.html).write_text(render_detection_page(score))
