"""The whole calibration, stage by stage, against known truth (conformance and simulated)."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from imucal import io, stages
from imucal.dataset import read_dataset
from imucal.filtering import lowpass_recording
from imucal.ingest import ingest_recording
from imucal.segmentation import segment_dataset

REPO = Path(__file__).resolve().parents[1]


def calibrate(folder: Path) -> tuple[dict, dict]:
    """Run every stage function in pipeline order, as the workflow does; return artifacts."""
    dataset = read_dataset(folder)
    tables = {
        name: ingest_recording(path, recording=name, dataset=dataset, imucal_version="test")
        for name, path in dataset.recordings.items()
    }
    imu = {k: v[0] for k, v in tables.items() if k != "reference"}
    segments = segment_dataset(imu, ratetable=dataset.ratetable)
    low = lowpass_recording(imu["rotation3d"], order=4, cutoff_hz=5.0)
    limit_acc = dataset.range_counts["acc"] * dataset.sensitivity["acc"]
    limit_gyr = dataset.range_counts["gyr"] * dataset.sensitivity["gyr"]
    mag = stages.align_mag(
        imu["rotation3d"], segments, stages.fit_mag_step1(imu["rotation3d"], imu["cube"])
    )
    cube, _ = stages.fit_acc_cube(
        imu["cube"], segments, gravity_m_s2=dataset.gravity_m_s2, saturation_limit_m_s2=limit_acc
    )
    acc = stages.align_acc(low, segments, cube)
    bias, _ = stages.estimate_gyr_bias(imu, segments)
    o, _ = stages.gyr_bias_value(bias, "ls")
    alignment = stages.align_gyr(low, segments, o)
    scale = stages.estimate_gyr_scale(imu["rotation3d"], segments, bias, alignment, acc, mag)
    table, _ = stages.fit_gyr_table(imu["ratetable"], segments, saturation_limit_rad_s=limit_gyr)
    table_alignment = stages.align_gyr(low, segments, table["bias"], table["upper"])
    truth = json.loads((folder / "truth.json").read_text())
    gyr, _ = stages.combine_gyr(bias, alignment, scale, table, table_alignment, truth=truth)
    calibration = stages.combine_calibration(acc, gyr, mag).to_dict()
    return calibration, truth


def max_errors(calibration: dict, truth: dict, sensor: str) -> tuple[float, float]:
    matrix = np.abs(np.subtract(calibration[sensor]["matrix"], truth[sensor]["matrix"])).max()
    bias = np.abs(np.subtract(calibration[sensor]["bias"], truth[sensor]["bias"])).max()
    return float(matrix), float(bias)


def test_conformance_session_recovers_truth(conformance_dir):
    # Acceptance limits of the calibration issue; the noise-limited errors are 10-100x smaller
    # (docs/accuracy-*.md), so a pass is not luck.
    calibration, truth = calibrate(conformance_dir)
    limits = {"acc": (2e-3, 0.01), "gyr": (2e-3, 2e-4), "mag": (5e-3, 5e-3)}
    for sensor, (matrix_limit, bias_limit) in limits.items():
        matrix_err, bias_err = max_errors(calibration, truth, sensor)
        assert matrix_err < matrix_limit, (sensor, matrix_err)
        assert bias_err < bias_limit, (sensor, bias_err)


@pytest.mark.slow
def test_workflow_runs_on_a_simulated_session(tmp_path):
    """`snakemake --cores 2` on a temporary copy recovers the simulator's truth."""
    work = tmp_path / "work"
    work.mkdir()
    for name in ("Snakefile", "workflow", "config"):
        src = REPO / name
        (shutil.copytree if src.is_dir() else shutil.copy)(src, work / name)
    subprocess.run(
        ["imucal", "simulate", str(work / "data/sim"), "--preset", "paper", "--seed", "5",
         "--static-s", "30", "--name", "sim"],
        check=True, capture_output=True,
    )
    (work / "config/config.yaml").write_text("datasets:\n  sim: data/sim\n")
    run = subprocess.run(
        ["snakemake", "--cores", "2", "-q"], cwd=work, capture_output=True, text=True
    )
    assert run.returncode == 0, run.stderr[-3000:]
    calibration = json.loads((work / "results/sim/calibration.json").read_text())
    truth = json.loads((work / "data/sim/truth.json").read_text())
    for sensor in ("acc", "gyr", "mag"):
        matrix_err, bias_err = max_errors(calibration, truth, sensor)
        assert matrix_err < 5e-3, (sensor, matrix_err)
    html = (work / "reports/sim.html").read_text()
    assert html.count("<img") >= 8  # stage figures and the segment plots, embedded
    assert "Table I" in html
