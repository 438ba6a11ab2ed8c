"""Wrong inputs stop the workflow before any rule with one paragraph that names the config file,
the dataset's key, the folder or setting, and the fix (dry runs in a working copy)."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def _dry_run(
    tmp_path: Path,
    config: str,
    args: tuple = ("--configfile", "my.yaml"),
    files: dict | None = None,
) -> subprocess.CompletedProcess:
    """A dry run in a working copy with ``my.yaml`` and other ``files`` (path -> text)."""
    work = tmp_path / "work"
    work.mkdir(parents=True)
    for name in ("Snakefile", "config", "data", "workflow"):
        (work / name).symlink_to(REPO / name)
    (work / "my.yaml").write_text(config)
    for name, text in (files or {}).items():
        (work / name).parent.mkdir(parents=True, exist_ok=True)
        (work / name).write_text(text)
    return subprocess.run(
        [sys.executable, "-m", "snakemake", "--cores", "1", "-n", *args],
        cwd=work, env={**os.environ, "PYTHONPATH": str(REPO)},
        capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip


#: Most lines an error may print: it fits on a screen.
MAX_LINES = 15


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


@pytest.mark.parametrize(
    ("config", "expected"),
    [
        ("lowpas:\n  order: 4\n",
         "my.yaml: key 'lowpas' is not a setting, did you mean 'lowpass'? Settings at the top "
         "level: "),
        ("datasets:\n  demo: data/demo\nlowpass:\n  cutof_hz: 4.0\n",
         "my.yaml: key 'lowpass/cutof_hz' is not a setting, did you mean 'cutoff_hz'? Settings "
         "of 'lowpass': cutoff_hz, order"),
        ("terms:\n  temperatur: auto\n",
         "my.yaml: key 'terms/temperatur' is not a setting, did you mean 'temperature'?"),
        ("gap:\n  replica: 8\n",
         "my.yaml: key 'gap/replica' is not a setting, did you mean 'replicas'?"),
        ("lowpass:\n  cutoff_hz: five\n",
         "my.yaml: key 'lowpass/cutoff_hz': \"five\" breaks the schema's 'type \"number\"'. "
         "Expected: one-way -3 dB frequency, Hz."),
    ],
)  # fmt: skip
def test_a_config_error_names_the_file_the_key_and_the_fix_on_one_screen(
    tmp_path, config, expected
):
    run = _dry_run(tmp_path, config)
    assert run.returncode != 0
    output = (run.stdout + run.stderr).strip().splitlines()
    assert len(output) <= MAX_LINES, output
    assert _paragraph(run).startswith(expected), _paragraph(run)
    assert "Failed validating" not in run.stdout + run.stderr  # not the whole schema


def test_a_results_file_after_configfile_is_told_to_go_first(tmp_path):
    """``--configfile my.yaml results/demo/calibration.json`` reads the target as a config."""
    calibration = {"format_version": 2, "frame": "B", "convention": "x", "acc": {}, "gyr": {}}
    run = _dry_run(
        tmp_path, "datasets:\n  demo: data/demo\n",
        ("--configfile", "my.yaml", "results/demo/calibration.json"),
        {"results/demo/calibration.json": json.dumps(calibration)},
    )  # fmt: skip
    output = (run.stdout + run.stderr).strip().splitlines()
    assert run.returncode != 0 and len(output) <= MAX_LINES, output
    message = _paragraph(run)
    assert message.startswith(
        "results/demo/calibration.json was read as a config file, but it looks like a results "
        "file (it lies under results/ or reports/)"
    )
    assert "(snakemake --cores 2 results/demo/calibration.json --configfile my.yaml)" in message
    assert "--configfile=my.yaml results/demo/calibration.json" in message


def test_a_target_after_forcerun_is_told_to_go_first(tmp_path):
    """``--forcerun ingest TARGET`` reads the target as a file to rerun and, naming no target,
    would plan the whole workflow."""
    args = ("--forcerun", "ingest", "results/demo/ingest/summary.json")
    run = _dry_run(tmp_path, "datasets:\n  demo: data/demo\n", ("--configfile=my.yaml", *args))
    output = (run.stdout + run.stderr).strip().splitlines()
    assert run.returncode != 0 and len(output) <= MAX_LINES, output
    message = _paragraph(run)
    assert message.startswith(
        "--forcerun took 'results/demo/ingest/summary.json' as a file to rerun, not as a target"
    )
    assert "(snakemake --cores 2 results/demo/ingest/summary.json --forcerun ingest)" in message
    assert "Job stats" not in run.stdout
    # written the right way, the same command plans the ingest alone
    right = _dry_run(
        tmp_path / "right", "datasets:\n  demo: data/demo\n",
        ("results/demo/ingest/summary.json", "--forcerun", "ingest"),
    )  # fmt: skip
    assert right.returncode == 0, right.stderr[-2000:]
    assert "rule report" not in right.stdout and "rule ingest:" in right.stdout
