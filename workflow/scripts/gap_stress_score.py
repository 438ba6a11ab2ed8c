"""Rule stress_score: unseal the answer keys and score the stress diagnoses (+ report page)."""

import logging
from pathlib import Path
from typing import TYPE_CHECKING

import pandas as pd

from imucal.gap.stress import render_stress_page, score_stress
from imucal.io import read_json, write_json

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

logging.basicConfig(filename=snakemake.log[0], filemode="w", level=logging.INFO)
name = lambda path: Path(path).stem
diagnoses = {name(f): read_json(f) for f in snakemake.input.diagnoses}
keys = {name(f): read_json(f) for f in snakemake.input.sealed}
score = score_stress(diagnoses, keys)
seconds = [float(pd.read_csv(f, sep="\t")["s"].iloc[0]) for f in snakemake.input.benchmarks]
score["diagnosis_seconds"] = {"median": float(pd.Series(seconds).median()), "max": max(seconds)}
write_json(score, snakemake.output.score)
Path(snakemake.output.html).write_text(render_stress_page(score))
