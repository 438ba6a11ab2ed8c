"""Partial sessions: which stages run, why the others are skipped, and the results vs truth."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from conftest import partial_session

from imucal import errormodel
from imucal.calibration import SensorCalibration
from imucal.columns import GYR
from imucal.io.dataset import read_dataset
from imucal.pipeline import partial, registry
from imucal.segments.segmentation import segment_dataset
from imucal.segments.table import rows_of
from imucal.sim import simulate

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def session(tmp_path_factory, ingest_imu):
    """A simulated paper session (seed 3), ingested and segmented like the workflow does."""
    folder = tmp_path_factory.mktemp("partial") / "s"
    simulate(folder, preset="paper", seed=3, static_s=30)
    dataset = read_dataset(folder)
    tables = ingest_imu(dataset)
    segments = segment_dataset(tables, ratetable=dataset.ratetable)
    truth = json.loads((folder / "truth.json").read_text())
    return dataset, tables, segments, truth


#: Largest |error| / reported std of a matrix entry (9 entries, two sessions' paths: a
#: normal error exceeds 4.5 with probability 6.8e-6 each).
MAX_Z = 4.5


def assert_matrix_within_its_std(calibration: dict, sensor: str, truth: np.ndarray) -> None:
    """Every entry of the calibration's matrix within :data:`MAX_Z` of its reported std (the
    entries below the diagonal of an upper-triangular factor have none and must be exact)."""
    cal = SensorCalibration.from_dict(sensor, calibration)
    std = np.sqrt(np.diag(cal.covariance)[3:12]).reshape(3, 3)
    error = cal.matrix - truth
    assert np.all(np.abs(error) <= MAX_Z * std), (sensor, error, std)


def statuses(outcomes):
    return {o.name: o.status for o in outcomes}


def test_platform_without_tools_runs_the_tool_free_path(session):
    dataset, tables, segments, truth = session
    inputs = partial_session(
        {k: tables[k] for k in ("rotation3d", "static")}, segments, dataset.gravity_m_s2
    )
    outcomes = partial.run_stages(inputs)
    ran = {name for name, status in statuses(outcomes).items() if status == "run"}
    assert ran == {"mag_step1", "mag_step2", "gyr_bias", "gyr_align", "gyr_scale"}
    reasons = {o.name: o.reason for o in outcomes}
    assert "static poses" in reasons["acc_cube"] and "ratetable" in reasons["gyr_table"]
    final = partial.final_calibration(outcomes, inputs.options)
    assert set(final["sensors"]) == {"mag", "gyr"}
    assert "acc_cube" in final["missing"]["acc"]
    mag = np.array(final["sensors"]["mag"]["calibration"]["matrix"])
    assert np.abs(mag - truth["mag"]["matrix"]).max() < 5e-3  # the mag limit
    # seen: at most 2.3 std
    assert_matrix_within_its_std(
        final["sensors"]["mag"]["calibration"], "mag", truth["mag"]["matrix"]
    )
    # eq. 36 scale: noise std ~1e-4 here; the unobservable non-orthogonality (~1e-2 rad) adds a
    # systematic part of order xi^2 .. xi * alpha, so 1e-3 relative is the honest bound
    scale = np.array(final["sensors"]["gyr"]["calibration"]["matrix"])
    true_scale = errormodel.decompose(np.array(truth["gyr"]["matrix"])).scale
    estimated = errormodel.decompose(scale).scale
    assert np.all(np.abs(estimated / true_scale - 1) < 1e-3)
    # the same calibration as the paper's path without a rate table, with its covariance
    gyr = final["sensors"]["gyr"]["calibration"]
    assert np.shape(gyr["covariance"]["matrix"]) == (21, 21)
    assert np.all(np.asarray(gyr["std"]["alpha_rad"]) > 0)


def test_hand_placed_poses_give_cube_fit_and_pose_to_pose_gyro(session):
    dataset, tables, segments, truth = session
    poses = segments.copy()
    poses.loc[poses["recording"] == "cube", "recording"] = "poses"
    inputs = partial_session(
        {"poses": tables["cube"], "static": tables["static"]}, poses, dataset.gravity_m_s2
    )
    outcomes = partial.run_stages(inputs)
    status = statuses(outcomes)
    assert status["acc_cube"] == "run" and status["gyr_pose_to_pose"] == "run"
    assert status["acc_align"] == "skipped" and status["gyr_align"] == "skipped"
    final = partial.final_calibration(outcomes, inputs.options)
    # without T_R the accelerometer is in the frame F of its upper-triangular factor:
    # truth matrix = Q U, so the cube fit recovers U and the pose-to-pose gyro Q^T M_gyr
    q, upper = errormodel.upper_triangular_factor(np.array(truth["acc"]["matrix"]))
    acc = np.array(final["sensors"]["acc"]["calibration"]["matrix"])
    gyr = np.array(final["sensors"]["gyr"]["calibration"]["matrix"])
    assert np.abs(acc - upper).max() < 2e-3  # the acc limit (measured 2.6e-4)
    assert np.abs(gyr - q.T @ np.array(truth["gyr"]["matrix"])).max() < 2e-3  # measured 4.7e-4
    # seen: at most 2.2 std (acc) and 1.0 std (gyr)
    assert_matrix_within_its_std(final["sensors"]["acc"]["calibration"], "acc", upper)
    assert_matrix_within_its_std(
        final["sensors"]["gyr"]["calibration"], "gyr", q.T @ np.array(truth["gyr"]["matrix"])
    )
    figures = partial.figures(outcomes, {"poses": tables["cube"], "static": tables["static"]})
    assert set(figures) == {"mag_raw", "mag_step1", "acc_cube", "gyr_pose_to_pose"}
    bars = figures["gyr_pose_to_pose"].axes[1].patches
    assert len(bars) == len(poses[(poses["recording"] == "poses")]) - 1  # one per interval


def test_turns_through_clipped_gyro_readings_are_left_out_of_pose_to_pose(session):
    # the cube's gyro clipped below the peak rate of five of its eleven turns: a clipped turn
    # integrates too small an angle, so it is left out and named, and the rest still fit
    dataset, tables, segments, truth = session
    poses = segments.copy()
    poses.loc[poses["recording"] == "cube", "recording"] = "poses"
    rows = rows_of(poses, "poses", "position", "static")
    w = tables["cube"][list(GYR)].to_numpy()
    middles = ((rows["start_index"] + rows["end_index"]) // 2).to_numpy()
    peaks = np.array([np.abs(w[a : b + 1]).max() for a, b in zip(middles[:-1], middles[1:])])
    labels = rows["label"].astype(str).to_numpy()
    names = [f"{a}-{b}" for a, b in zip(labels[:-1], labels[1:])]

    def pose_to_pose(limit: float):
        clipped = tables["cube"].copy()
        clipped[list(GYR)] = np.clip(w, -limit, limit)
        outcomes = partial.run_stages(
            partial_session(
                {"poses": clipped, "static": tables["static"]},
                poses,
                dataset.gravity_m_s2,
                ranges={"gyr": limit},
            )
        )
        return {o.name: o for o in outcomes}["gyr_pose_to_pose"]

    limit = 0.9 * np.sort(peaks)[-4]
    fit = pose_to_pose(limit)
    assert fit.status == "run"
    assert fit.artifact["left_out_clipped"] == [n for n, p in zip(names, peaks) if p > limit]
    assert len(fit.artifact["left_out_clipped"]) == 5
    assert any("5 turns between poses left out" in x for x in fit.artifact["warnings"])
    q, _ = errormodel.upper_triangular_factor(np.array(truth["acc"]["matrix"]))
    # seen: 0.8 std with the clipped turns left out (3.5 std with them in)
    assert_matrix_within_its_std(
        fit.artifact["calibration"], "gyr", q.T @ np.array(truth["gyr"]["matrix"])
    )
    # too few turns left: refused with the count, not fitted on clipped turns
    refused = pose_to_pose(0.99 * np.sort(peaks)[4])
    assert refused.status == "skipped"
    assert "4 of 11 turns between poses without clipped gyroscope readings, expected >= 5" in (
        refused.reason
    )


def test_a_fit_that_fails_on_the_data_is_skipped_with_its_message(session):
    dataset, tables, segments, _ = session
    # only the first 4 cube positions: too few for the 9 parameters of eq. 32
    rows = segments[(segments["recording"] == "cube") & (segments["kind"] == "position")]
    few = segments.drop(rows.index[4:])
    outcomes = partial.run_stages(
        partial_session({"cube": tables["cube"]}, few, dataset.gravity_m_s2)
    )
    reason = {o.name: o.reason for o in outcomes}["acc_cube"]
    assert reason.startswith("not applicable: needs >= 9 static poses")
    assert all(o.status == "skipped" for o in outcomes if o.name.startswith("acc"))


def test_declared_sensors_decide_the_workflow_path(tmp_path):
    demo = read_dataset(REPO / "data" / "demo")
    assert registry.is_full_protocol(demo)
    assert registry.declared_sensors(demo, "cube") == ("acc", "gyr", "mag")
    folder = tmp_path / "acc_only"
    folder.mkdir()
    (folder / "log.csv").write_text("ax,ay,az\n0,0,1\n0,0,1\n")
    (folder / "dataset.yaml").write_text(
        "name: acc_only\ngravity_m_s2: 9.81\nrecordings:\n  poses:\n    reader: table\n"
        "    file: log.csv\n    columns: {acc_x: ax, acc_y: ay, acc_z: az}\n    rate_hz: 100\n"
        "    units: {acc: g}\n"
    )
    dataset = read_dataset(folder)
    assert registry.declared_sensors(dataset, "poses") == ("acc",)
    assert not registry.is_full_protocol(dataset)


def test_known_angle_hand_turns_on_rotation3d_phases(session):
    """Phases with angle_deg (hand turns of a stated angle) feed the known-rotation gyro fit."""
    dataset, tables, segments, truth = session
    seg = segments.copy()
    phases = (seg["recording"] == "rotation3d") & (seg["kind"] == "phase")
    # the simulated phases turn (2, -2, 2) turns about x, y, z of B (ProtocolConfig)
    seg.loc[phases, "angle_deg"] = seg.loc[phases, "label"].map({"x": 720, "y": -720, "z": 720})
    inputs = partial_session(
        {k: tables[k] for k in ("rotation3d", "static")}, seg, dataset.gravity_m_s2
    )
    outcomes = partial.run_stages(inputs)
    known = next(o for o in outcomes if o.name == "gyr_known_rotation")
    assert known.status == "run", known.reason
    final = partial.final_calibration(outcomes, inputs.options)
    assert final["sensors"]["gyr"]["stage"] == "gyr_known_rotation"
    gyr = np.array(final["sensors"]["gyr"]["calibration"]["matrix"])
    # three 720-degree sections, noise-limited angles (~1e-4 rad) -> matrix error ~1e-5; the
    # phases also include their ramps, so the 2e-3 limit is a loose, honest bound
    assert np.abs(gyr - truth["gyr"]["matrix"]).max() < 2e-3
    # and within its reported std (seen: at most 1.5 std, errors 1.4e-4)
    assert_matrix_within_its_std(
        final["sensors"]["gyr"]["calibration"], "gyr", truth["gyr"]["matrix"]
    )
    # a gyroscope range below the turns' rates clips every section: none is fitted on
    clipped = partial.run_stages(
        partial_session(
            {k: tables[k] for k in ("rotation3d", "static")},
            seg,
            dataset.gravity_m_s2,
            ranges={"gyr": 0.05},
        )
    )
    refused = next(o for o in clipped if o.name == "gyr_known_rotation")
    assert refused.status == "skipped"
    assert "0 rotation sections with a known angle without clipped readings (3 left out)" in (
        refused.reason
    )


def test_rotation_sections_run_from_rest_to_rest():
    """A section is widened to the middle of a rest beside it, not into another motion."""
    import pandas as pd

    segments = pd.DataFrame(
        {
            "recording": ["r"] * 5 + ["other"],
            "label": ["s01", "x", "t01", "y", "p01", "s01"],
            "kind": ["static", "phase", "transition", "phase", "position", "static"],
            "start_index": [0, 100, 300, 350, 500, 0],
            "end_index": [100, 300, 350, 500, 601, 1000],
        }
    )
    phases = segments[segments["kind"] == "phase"]
    wide = partial.rest_to_rest(segments, "r", phases)
    assert wide["start_index"].tolist() == [50, 350]  # before y: a transition, kept
    assert wide["end_index"].tolist() == [300, 551]  # after x: a transition, kept
    assert phases["start_index"].tolist() == [100, 350]  # the input is not changed
    # a rest with other motion between it and the section (a gap) is not next to it
    apart = segments.assign(start_index=[0, 110, 300, 350, 520, 0])
    wide = partial.rest_to_rest(apart, "r", apart[apart["kind"] == "phase"])
    assert wide["start_index"].tolist() == [110, 350]
    assert wide["end_index"].tolist() == [300, 500]
    # next to it: within ADJACENT_SAMPLES of the section, to the sample
    from imucal.pipeline.partial.gyroscope import ADJACENT_SAMPLES as near

    for gap, widened in ((near, True), (near + 1, False)):
        shifted = segments.assign(start_index=[0, 100 + gap, 300, 350, 500 + gap, 0])
        wide = partial.rest_to_rest(shifted, "r", shifted[shifted["kind"] == "phase"])
        assert (wide["start_index"].tolist()[0] == 50) == widened, gap
        assert (wide["end_index"].tolist()[1] == 551 + gap // 2) == widened, gap


def test_a_fit_worse_than_nominal_on_left_out_positions_is_not_shipped():
    from imucal.calibration import SensorCalibration
    from imucal.pipeline.partial import review

    cal = SensorCalibration("acc", np.zeros(3), np.eye(3), "m/s^2").to_dict()
    good = {"calibration": cal, "heldout_error_before_m_s2": [0.3] * 10,
            "heldout_error_after_m_s2": [0.02] * 10}  # fmt: skip
    assert review("acc_cube", {"acc_cube": good}) == {"refuse": [], "warn": []}
    bad = {**good, "heldout_error_after_m_s2": [0.5] * 10}
    (reason,) = review("acc_cube", {"acc_cube": bad})["refuse"]
    assert "worse than the nominal calibration (RMS 0.5 against 0.3 over 10 left-out" in reason


def test_a_review_that_fails_is_a_bug_and_stops_the_run(session, monkeypatch):
    # only a refused fit is the data's verdict; an error inside the review must not pass
    # for "could not be fitted" and ship the next, simpler stage
    from imucal.validation import plausibility

    def broken(*args, **kwargs):
        raise ValueError("shapes (3,) and (2,) not aligned")

    monkeypatch.setattr(plausibility, "review_fit", broken)
    dataset, tables, segments, _ = session
    with pytest.raises(RuntimeError, match="the review of .* failed: shapes"):
        partial.run_stages(
            partial_session(
                {k: tables[k] for k in ("rotation3d", "static")}, segments, dataset.gravity_m_s2
            )
        )
