"""The lab report reads the log of every rule behind it, so that every logged warning reaches
it (a dry run of the workflow lists the jobs a report needs and their logs)."""

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
REAL = REPO.parent / "shared" / "data" / "real"


def _plan(tmp_path: Path, target: str) -> str:
    work = tmp_path / "work"
    work.mkdir()
    for name in ("Snakefile", "config", "data", "workflow"):
        (work / name).symlink_to(REPO / name)
    if REAL.is_dir():
        (tmp_path / "shared").symlink_to(REAL.parent.parent / "shared")
    run = subprocess.run(
        [sys.executable, "-m", "snakemake", "-n", "--forceall", "--cores", "1", target],
        cwd=work, env={**os.environ, "PYTHONPATH": str(REPO)},
        capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr[-2000:]
    return run.stdout


@pytest.mark.parametrize(
    "dataset",
    ["demo", pytest.param("mad_lab_ferraris", marks=pytest.mark.skipif(
        not REAL.is_dir(), reason="../shared/data/real is absent (public recordings)"))],
)  # fmt: skip
def test_the_report_reads_the_log_of_every_rule_behind_it(tmp_path, dataset):
    plan = _plan(tmp_path, f"reports/{dataset}.html")
    logs = set(re.findall(r"^\s*log: (\S+)$", plan, flags=re.MULTILINE))
    report_log = f"results/{dataset}/logs/report.log"
    assert report_log in logs
    job = plan[plan.index("rule report:") :]
    inputs = set(re.search(r"^\s*input: (.*)$", job, flags=re.MULTILINE)[1].split(", "))
    assert logs - {report_log} <= inputs, sorted(logs - {report_log} - inputs)
    assert len(logs) > 5
