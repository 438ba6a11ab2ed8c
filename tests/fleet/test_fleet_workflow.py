"""The fleet target plans the calibration of every session of a sample sheet, then its report."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def fleet_jobs(tmp_path, *config: str) -> dict:
    """Jobs per rule of a dry run of the fleet target over five sessions of the demo."""
    for name in ("Snakefile", "config", "data", "workflow", "imucal"):
        (tmp_path / name).symlink_to(REPO / name)
    rows = [f"unit_{k}\t{REPO / 'data' / 'demo'}\tS{k % 3}\t2026-0{k}-01\tana" for k in range(1, 6)]
    sheet = tmp_path / "sessions.tsv"
    sheet.write_text("dataset\tpath\tserial\tdate\toperator\n" + "\n".join(rows) + "\n")
    run = subprocess.run(
        [sys.executable, "-m", "snakemake", "fleet", "--config", f"fleet={{sessions: {sheet}}}",
         *config, "--dry-run", "--quiet", "rules"],
        cwd=tmp_path, env={**os.environ, "PYTHONPATH": str(REPO)},
        capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip
    assert run.returncode == 0, run.stdout + run.stderr
    return dict(
        line.split()
        for line in run.stdout.splitlines()
        if line.split() and line.split()[0] in {"calibration", "fleet_report", "gap_diagnose"}
    )


def test_the_fleet_target_calibrates_each_session_of_the_sheet(tmp_path) -> None:
    # the model terms are 'auto' by default: each calibration waits for its diagnosis
    assert fleet_jobs(tmp_path) == {"calibration": "5", "fleet_report": "1", "gap_diagnose": "5"}


def test_with_the_terms_off_the_fleet_calibrates_without_diagnosing(tmp_path) -> None:
    off = "terms={temperature: 'off', g_sensitivity: 'off', mag_delay: 'off', lever_arm: 'off'}"
    assert fleet_jobs(tmp_path, off) == {"calibration": "5", "fleet_report": "1"}


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
