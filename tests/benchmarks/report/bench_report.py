"""Benchmark of the lab report on a 10-minute session, against the fits in the same run.

A script, not a test (speed is measured, never asserted). It simulates a session of about
``--minutes`` minutes of recordings (preset demo; the long static recording takes the time the
protocol does not), runs the whole workflow on it with ``snakemake --cores 2`` in a temporary
copy of the workflow, and reads the ``benchmark:`` files of the rules. It prints the wall time of
the ``report`` rule (target: under 30 s), the total of the calibration fit rules, and their ratio.

Run: ``python tests/benchmarks/report/bench_report.py [--minutes 10]``.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import tempfile
from pathlib import Path

import pandas as pd

from imucal.ingest import ingest_recording
from imucal.io.dataset import read_dataset

REPO = Path(__file__).resolve().parents[3]
FIT_RULES = (
    "segment",
    "mag_step1",
    "mag_step2",
    "acc_cube",
    "acc_align",
    "gyr_bias",
    "gyr_align",
    "gyr_scale",
    "gyr_table",
    "validate",
)


def session_minutes(folder: Path) -> float:
    """Total duration of the module's recordings of a session folder, minutes."""
    dataset = read_dataset(folder)
    total = 0.0
    for name, path in dataset.recordings.items():
        if name == "reference":
            continue
        table, _ = ingest_recording(path, recording=name, dataset=dataset, imucal_version="bench")
        total += float(table["t_s"].iloc[-1] - table["t_s"].iloc[0])
    return total / 60


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=10.0)
    parser.add_argument("--seed", type=int, default=7)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        for name in ("Snakefile", "workflow", "config"):
            src = REPO / name
            (shutil.copytree if src.is_dir() else shutil.copy)(src, work / name)
        probe = work / "data" / "probe"
        subprocess.run(
            [
                "imucal",
                "simulate",
                str(probe),
                "--preset",
                "demo",
                "--seed",
                str(args.seed),
                "--static-s",
                "10",
                "--name",
                "probe",
            ],
            check=True,
            capture_output=True,
        )
        static_s = max(10.0, args.minutes * 60 - (session_minutes(probe) * 60 - 10))
        folder = work / "data" / "long"
        subprocess.run(
            [
                "imucal",
                "simulate",
                str(folder),
                "--preset",
                "demo",
                "--seed",
                str(args.seed),
                "--static-s",
                f"{static_s:.0f}",
                "--name",
                "long",
            ],
            check=True,
            capture_output=True,
        )
        minutes = session_minutes(folder)
        (work / "config" / "config.yaml").write_text("datasets:\n  long: data/long\n")
        run = subprocess.run(
            ["snakemake", "--cores", "2", "-q"], cwd=work, capture_output=True, text=True
        )
        if run.returncode != 0:
            raise SystemExit(f"snakemake failed:\n{run.stderr[-3000:]}")
        bench = work / "results" / "long" / "benchmarks"
        seconds = {
            p.stem: float(pd.read_csv(p, sep="\t")["s"].iloc[0]) for p in bench.glob("*.tsv")
        }
        fits = sum(seconds[r] for r in FIT_RULES if r in seconds)
        html = work / "reports" / "long.html"
        result = {
            "session_minutes": round(minutes, 2),
            "report_s": seconds["report"],
            "fit_rules_s": round(fits, 2),
            "report_over_fits": round(seconds["report"] / fits, 3),
            "report_mb": round(html.stat().st_size / 1e6, 2),
        }
        print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
