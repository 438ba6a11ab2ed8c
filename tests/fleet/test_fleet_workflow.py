"""The fleet target plans the calibration of every session of a sample sheet, then its report."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def test_the_fleet_target_calibrates_each_session_of_the_sheet(tmp_path) -> None:
    for name in ("Snakefile", "config", "data", "workflow", "imucal"):
        (tmp_path / name).symlink_to(REPO / name)
    rows = [f"unit_{k}\t{REPO / 'data' / 'demo'}\tS{k % 3}\t2026-0{k}-01\tana" for k in range(1, 6)]
    sheet = tmp_path / "sessions.tsv"
    sheet.write_text("dataset\tpath\tserial\tdate\toperator\n" + "\n".join(rows) + "\n")
    run = subprocess.run(
        [sys.executable, "-m", "snakemake", "fleet", "--config", f"fleet={{sessions: {sheet}}}",
         "--dry-run", "--quiet", "rules"],
        cwd=tmp_path, env={**os.environ, "PYTHONPATH": str(REPO)},
        capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip
    assert run.returncode == 0, run.stdout + run.stderr
    jobs = dict(
        line.split()
        for line in run.stdout.splitlines()
        if line.split() and line.split()[0] in {"calibration", "fleet_report", "gap_diagnose"}
    )
    assert jobs == {"calibration": "5", "fleet_report": "1"}


def test_the_fleet_target_without_a_sheet_says_what_to_set(tmp_path) -> None:
    for name in ("Snakefile", "config", "data", "workflow", "imucal"):
        (tmp_path / name).symlink_to(REPO / name)
    run = subprocess.run(
        [sys.executable, "-m", "snakemake", "fleet", "--dry-run"],
        cwd=tmp_path, env={**os.environ, "PYTHONPATH": str(REPO)},
        capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip
    assert run.returncode != 0
    assert "set config fleet.sessions" in run.stdout + run.stderr
