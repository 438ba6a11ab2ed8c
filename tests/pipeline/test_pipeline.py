"""The whole calibration, stage by stage, against known truth (conformance and simulated)."""

from __future__ import annotations

import json
import shutil
import subprocess
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from conftest import z_limit
from scipy import stats
from scipy.spatial.transform import Rotation

from imucal.calibration import ImuCalibration
from imucal.columns import SENSORS
from imucal.ingest import ingest_recording
from imucal.io.dataset import read_dataset
from imucal.pipeline import stages
from imucal.pipeline.full import PipelineOptions, calibrate_session

REPO = Path(__file__).resolve().parents[2]


def calibrate(folder: Path) -> tuple[dict, dict, dict]:
    """Ingest a session and run the paper's chain on it, as the workflow does.

    Returns the calibration dict, the session's truth.json, and the stage inputs (``tables``:
    ingested recordings with their metadata, ``segments``, ``lowpass``).
    """
    dataset = read_dataset(folder)
    tables = {
        name: ingest_recording(path, recording=name, dataset=dataset, imucal_version="test")
        for name, path in dataset.recordings.items()
    }
    imu = {k: v[0] for k, v in tables.items() if k != "reference"}
    fit = calibrate_session(imu, None, PipelineOptions.of_dataset(dataset))
    truth = json.loads((folder / "truth.json").read_text())
    inputs = {"tables": tables, "segments": fit.segments, "lowpass": fit.lowpass}
    return fit.calibration.to_dict(), truth, inputs


def test_without_covariance_the_chain_fits_the_same_values(ingest_imu):
    # the twin's replicas run the chain without the uncertainty propagation: only the
    # covariance goes, the same arithmetic gives the fitted values (equal to rounding)
    dataset = read_dataset(REPO / "data" / "demo")
    imu = ingest_imu(dataset)
    options = PipelineOptions.of_dataset(dataset)
    full = calibrate_session(imu, None, options)
    bare = calibrate_session(imu, None, replace(options, with_covariance=False), full.segments)
    for sensor in SENSORS:
        a, b = full.calibration.sensor(sensor), bare.calibration.sensor(sensor)
        np.testing.assert_allclose(b.matrix, a.matrix, rtol=1e-12, atol=0)
        np.testing.assert_allclose(b.bias, a.bias, rtol=1e-12, atol=0)
        assert a.covariance is not None and a.std
        assert b.covariance is None and b.std == {}
    for align in ("gyr_align", "acc_align", "mag_step2"):
        step2 = full.artifacts[align].get("step2", full.artifacts[align])
        bare_step2 = bare.artifacts[align].get("step2", bare.artifacts[align])
        np.testing.assert_allclose(
            bare_step2["full"]["alpha_rad"], step2["full"]["alpha_rad"], rtol=1e-12, atol=0
        )
    assert (
        "sensitivity" in full.artifacts["gyr_align"]
        and "sensitivity" not in bare.artifacts["gyr_align"]
    )


def max_errors(calibration: dict, truth: dict, sensor: str) -> tuple[float, float]:
    matrix = np.abs(np.subtract(calibration[sensor]["matrix"], truth[sensor]["matrix"])).max()
    bias = np.abs(np.subtract(calibration[sensor]["bias"], truth[sensor]["bias"])).max()
    return float(matrix), float(bias)


#: Largest |error| / reported std of one parameter: the two-sided bound of the 12 (bias,
#: matrix) entries of three sensors at 1e-4 (4.7).
MAX_Z = z_limit(36)
#: chi-square(12) quantile at 1 - 1e-4: the Mahalanobis distance of one sensor's (bias,
#: matrix) error with its reported 12 x 12 covariance.
MAX_MAHALANOBIS = float(stats.chi2.ppf(1 - 1e-4, 12))


def assert_within_reported_covariance(calibration: dict, truth: dict, sensor: str) -> None:
    """The error of every bias and matrix entry of ``sensor`` against the std and covariance
    that calibration.json reports for it (the scales and angles are functions of these)."""
    cal = ImuCalibration.from_dict(calibration).sensor(sensor)
    error = np.r_[
        np.subtract(cal.bias, truth[sensor]["bias"]),
        np.subtract(cal.matrix, truth[sensor]["matrix"]).ravel(),
    ]
    covariance = cal.covariance[:12, :12]
    z = error / np.sqrt(np.diag(covariance))
    assert np.all(np.abs(z) < MAX_Z), (sensor, z.round(2))
    distance = float(error @ np.linalg.solve(covariance, error))
    assert distance < MAX_MAHALANOBIS, (sensor, distance)


def assert_outputs_match_the_truth(results: Path, data: Path, truth: dict) -> None:
    """The workflow's other estimates against the simulator's truth, each within :data:`MAX_Z`
    of the std it reports: the time offset and drift of the reference and its mounting
    (validation.json), the white noise N of every axis (noise.json; within twice that, as the
    fit's standard errors underestimate its spread about twofold, tests/noise), and no model
    term on a session without the effects (terms.json)."""
    import pandas as pd

    validation = json.loads((results / "validation.json").read_text())
    ref = truth["reference"]
    timing = validation["time_alignment"]
    # t_ref = offset + (1 + drift) t_module, t_ref on the reference's own clock (its first
    # sample is where the truth's tau starts)
    first_ref_s = float(pd.read_parquet(results / "ingest/reference.parquet")["t_s"].iloc[0])
    drift = 1 + ref["clock_drift_ppm"] * 1e-6
    offset_error = timing["offset_s"] - (first_ref_s + ref["time_offset_s"] * drift)
    assert abs(offset_error) < MAX_Z * timing["offset_std_s"], (offset_error, timing)
    drift_error = timing["drift_ppm"] - ref["clock_drift_ppm"]
    assert abs(drift_error) < MAX_Z * timing["drift_std_ppm"], (drift_error, timing)
    mounting = validation["mounting"]
    error_deg = np.degrees(
        (
            Rotation.from_rotvec(mounting["rotvec_rad"])
            * Rotation.from_rotvec(ref["mounting_rotvec_rad"]).inv()
        ).magnitude()
    )
    assert error_deg < MAX_Z * mounting["angle_std_deg"], (error_deg, mounting)

    noise = json.loads((results / "noise.json").read_text())
    sensitivity = read_dataset(data).sensitivity
    for sensor, fit in noise["sensors"].items():
        # the simulator's white noise plus the rounding to counts (variance step^2 / 12)
        variance = truth["noise"][sensor] ** 2 + sensitivity[sensor] ** 2 / 12
        want = np.sqrt(variance / fit["rate_hz"])
        for axis, terms in fit["axes"].items():
            n = terms["terms"]["N"]
            assert n["resolved"], (sensor, axis)
            assert abs(n["value"] - want) < MAX_Z * 2 * n["std"], (sensor, axis, n, want)

    terms = json.loads((results / "terms.json").read_text())
    assert terms["in_model"] == [], terms["in_model"]


def test_conformance_session_recovers_truth(conformance_dir):
    """The acceptance limits of the calibration (the noise-limited errors are 10-100x smaller,
    docs/accuracy-*.md), and every bias and matrix entry within the reported covariance: seen
    at most 1.9 std, Mahalanobis distances 9.4, 10.4 and 3.3 (limit 33.7)."""
    calibration, truth, _ = calibrate(conformance_dir)
    limits = {"acc": (2e-3, 0.01), "gyr": (2e-3, 2e-4), "mag": (5e-3, 5e-3)}
    for sensor, (matrix_limit, bias_limit) in limits.items():
        matrix_err, bias_err = max_errors(calibration, truth, sensor)
        assert matrix_err < matrix_limit, (sensor, matrix_err)
        assert bias_err < bias_limit, (sensor, bias_err)
        assert_within_reported_covariance(calibration, truth, sensor)


def test_demo_validation_finds_the_simulated_time_offset_and_mounting():
    """Time alignment: offset within one sample, mounting rotation within 0.1 degree, both
    within :data:`MAX_Z` of their reported std."""
    calibration, truth, inputs = calibrate(REPO / "data" / "demo")
    rotation3d, metadata = inputs["tables"]["rotation3d"]
    reference, _ = inputs["tables"]["reference"]
    result = stages.validate_session(
        rotation3d,
        metadata,
        reference,
        inputs["segments"],
        ImuCalibration.from_dict(calibration),
    )
    ref = truth["reference"]
    # truth: tau = (t_module + offset) (1 + drift), tau counted from the first reference sample;
    # validation: t_ref = offset_s + (1 + drift_ppm 1e-6) t_module on the reference's own clock.
    first_ref_s = float(reference["t_s"].iloc[0])
    drift = 1 + ref["clock_drift_ppm"] * 1e-6
    expected_offset_s = first_ref_s + ref["time_offset_s"] * drift
    one_sample_s = 1 / truth["sample_rate_hz"]
    timing = result["time_alignment"]
    assert abs(timing["offset_s"] - expected_offset_s) < one_sample_s
    # and within the reported std (about 0.5 ms, 1/20 of a sample)
    assert abs(timing["offset_s"] - expected_offset_s) < MAX_Z * timing["offset_std_s"], timing
    estimated = Rotation.from_rotvec(result["mounting"]["rotvec_rad"])
    error_deg = np.degrees(
        (estimated * Rotation.from_rotvec(ref["mounting_rotvec_rad"]).inv()).magnitude()
    )
    assert error_deg < 0.1
    assert error_deg < MAX_Z * result["mounting"]["angle_std_deg"], result["mounting"]
    # "much better than the raw one": the raw errors are 10-100x the noise floor here
    metrics = result["metrics"]
    for sensor in ("acc", "gyr", "mag"):
        raw = metrics["raw"][sensor]["rms_norm_diff"]
        assert metrics["calibrated"][sensor]["rms_norm_diff"] < raw / 5, sensor
    print(
        json.dumps(
            {
                "offset_error_s": timing["offset_s"] - expected_offset_s,
                "mounting_error_deg": error_deg,
            }
        )
    )


def test_jittered_receive_times_integrate_on_the_packet_counter(tmp_path):
    """Bursty receive stamps (equal times) must not break eq. 36: the counter gives the times."""
    from imucal.sim import make_effect, simulate

    folder = tmp_path / "jitter"
    simulate(folder, preset="paper", seed=11, static_s=30, effects=(make_effect("timing_jitter"),))
    calibration, truth, _ = calibrate(folder)
    for sensor, (matrix_limit, bias_limit) in {"acc": (2e-3, 0.01), "gyr": (2e-3, 2e-4)}.items():
        matrix_err, bias_err = max_errors(calibration, truth, sensor)
        assert matrix_err < matrix_limit and bias_err < bias_limit, (sensor, matrix_err, bias_err)
        assert_within_reported_covariance(calibration, truth, sensor)


def test_phase_figures_show_the_alignment_at_work():
    """Figs. 18-19 on the demo: after T_R the gyro rate of phase x lies on x_B, before it not."""
    calibration, _, inputs = calibrate(REPO / "data" / "demo")
    figure = stages.plot_phases(inputs["lowpass"], inputs["segments"], "gyr", calibration["gyr"])
    panels = figure.axes
    assert len(panels) == 6  # phases x, y, z; before and after
    assert [p.get_title() for p in panels[:2]] == [
        "phase x: before alignment",
        "phase x: after alignment",
    ]
    before, after = ([line.get_ydata() for line in p.get_lines()[:3]] for p in panels[:2])
    # off-axis rate (deg/s): misalignment of ~1e-2 rad times ~50 deg/s before; noise after
    off_before = np.sqrt(np.mean(np.square(before[1])) + np.mean(np.square(before[2])))
    off_after = np.sqrt(np.mean(np.square(after[1])) + np.mean(np.square(after[2])))
    assert off_after < off_before / 5, (off_before, off_after)
    with pytest.raises(ValueError, match="'acc' or 'gyr'"):
        stages.plot_phases(inputs["lowpass"], inputs["segments"], "mag", calibration["mag"])


@pytest.mark.slow
def test_workflow_runs_on_a_simulated_session(tmp_path):
    """`snakemake --cores 2` on a temporary copy recovers the simulator's truth."""
    work = tmp_path / "work"
    work.mkdir()
    for name in ("Snakefile", "workflow", "config"):
        src = REPO / name
        (shutil.copytree if src.is_dir() else shutil.copy)(src, work / name)
    subprocess.run(
        [
            "imucal",
            "simulate",
            str(work / "data/sim"),
            "--preset",
            "paper",
            "--seed",
            "5",
            "--static-s",
            "30",
            "--name",
            "sim",
        ],
        check=True,
        capture_output=True,
    )
    (work / "config/config.yaml").write_text("datasets:\n  sim: data/sim\n")
    run = subprocess.run(
        ["snakemake", "--cores", "2", "-q"], cwd=work, capture_output=True, text=True
    )
    assert run.returncode == 0, run.stderr[-3000:]
    calibration = json.loads((work / "results/sim/calibration.json").read_text())
    truth = json.loads((work / "data/sim/truth.json").read_text())
    for sensor in ("acc", "gyr", "mag"):
        assert_within_reported_covariance(calibration, truth, sensor)
    assert_outputs_match_the_truth(work / "results/sim", work / "data/sim", truth)
    html = (work / "reports/sim.html").read_text()
    assert html.count("<img") >= 8  # stage figures and the segment plots, embedded
    assert "Table I" in html
