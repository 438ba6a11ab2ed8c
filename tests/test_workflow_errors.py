"""Wrong inputs stop the workflow before any rule with one paragraph that names the config file,
the dataset's key, the folder or setting, and the fix (dry runs in a working copy)."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def _dry_run(tmp_path: Path, config: str) -> subprocess.CompletedProcess:
    work = tmp_path / "work"
    work.mkdir()
    for name in ("Snakefile", "config", "data", "workflow"):
        (work / name).symlink_to(REPO / name)
    (work / "my.yaml").write_text(config)
    return subprocess.run(
        [sys.executable, "-m", "snakemake", "--cores", "1", "--configfile", "my.yaml", "-n"],
        cwd=work, env={**os.environ, "PYTHONPATH": str(REPO)},
        capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip


def _paragraph(run: subprocess.CompletedProcess) -> str:
    """The message line of the error (Snakemake prints it after 'WorkflowError in file ...')."""
    lines = (run.stdout + run.stderr).splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("WorkflowError in file"))
    return lines[start + 1]


def test_a_missing_dataset_folder_names_config_key_and_path(tmp_path):
    run = _dry_run(tmp_path, "datasets:\n  lab1: data/lab1\n")
    assert run.returncode != 0
    message = _paragraph(run)
    assert message.startswith("my.yaml, datasets.lab1: 'data/lab1': the folder ")
    assert f"{tmp_path / 'work' / 'data' / 'lab1'} does not exist" in message
    assert "Give the folder that holds the dataset's dataset.yaml" in message
    assert "InputFunctionException" not in run.stdout + run.stderr
    assert "Job stats" not in run.stdout  # before any job is planned


@pytest.fixture
def misspelt(tmp_path) -> Path:
    folder = tmp_path / "session"
    folder.mkdir()
    for path in (REPO / "data" / "demo").iterdir():
        (folder / path.name).symlink_to(path)
    (folder / "dataset.yaml").unlink()
    text = (REPO / "data" / "demo" / "dataset.yaml").read_text()
    assert "\ngravity_m_s2:" in text
    (folder / "dataset.yaml").write_text(text.replace("\ngravity_m_s2:", "\ngravity_ms2:"))
    return folder


def test_a_misspelt_dataset_key_suggests_the_setting(tmp_path, misspelt):
    run = _dry_run(tmp_path, f"datasets:\n  lab1: {misspelt}\n")
    assert run.returncode != 0
    message = _paragraph(run)
    assert message.startswith(f"my.yaml, datasets.lab1: '{misspelt}': {misspelt}/dataset.yaml: ")
    assert "key 'gravity_ms2' is not a known key here, did you mean 'gravity_m_s2'?" in message
