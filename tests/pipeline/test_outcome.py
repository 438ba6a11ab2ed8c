"""Stages that cannot run on a session's data: not-run records, the guard of the rule scripts,
the calibration and stage listing built from what ran, and a diagnosis candidate whose replica
cannot be calibrated."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from imucal.calibration import SensorCalibration
from imucal.gap.attribution import Candidate, select_forward
from imucal.gap.null import NullModel
from imucal.pipeline.outcome import (
    StageNotRun,
    not_run_record,
    read_artifact,
    read_optional_artifact,
    stage_guard,
)
from imucal.pipeline.partial import full_protocol_stages
from imucal.pipeline.stages import calibration_of_what_ran


def test_guard_writes_every_output_as_not_run_and_the_next_stage_traces_it(tmp_path):
    outputs = {
        "fit": tmp_path / "acc_cube.json",
        "figure": tmp_path / "acc_cube.png",
        "tables": tmp_path / "tables.csv",
    }
    outputs["fit"].write_text("{}")  # a partial result of the failed body is overwritten
    with stage_guard("acc_cube", outputs):
        raise ValueError("cube: found 1 static position(s) (3.0-9.0 s); the cube fit needs 9")
    record = json.loads(outputs["fit"].read_text())
    assert record == not_run_record(
        "acc_cube", "cube: found 1 static position(s) (3.0-9.0 s); the cube fit needs 9"
    )
    assert outputs["figure"].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert list(pd.read_csv(outputs["tables"]).columns) == ["table", "row", "x", "y", "z"]
    assert read_optional_artifact(outputs["fit"]) is None
    with pytest.raises(StageNotRun, match=r"acc_cube did not run: cube: found 1 static"):
        read_artifact(outputs["fit"])
    # the next stage, reading it, is not run in turn with the reason traced back
    nxt = {"acc": tmp_path / "acc.json"}
    with stage_guard("acc_align", nxt):
        read_artifact(outputs["fit"])
    assert (
        "acc_cube did not run: cube: found 1"
        in json.loads(nxt["acc"].read_text())["not_run"]["reason"]
    )


def test_guard_lets_errors_that_are_not_about_the_data_through(tmp_path):
    out = {"fit": tmp_path / "x.json"}
    with pytest.raises(FileNotFoundError), stage_guard("acc_cube", out):
        raise FileNotFoundError("results/x/ingest/cube.parquet")
    assert not out["fit"].exists()


def _sensor(sensor, unit):
    return SensorCalibration(sensor, np.zeros(3), np.eye(3), unit, {}, "test").to_dict()


def test_calibration_names_the_sensor_whose_stages_did_not_run():
    artifacts = {
        "acc": {"calibration": _sensor("acc", "m/s^2")},
        "gyr": not_run_record("gyr", "gyr_scale did not run: phases clipped"),
        "mag": {"calibration": _sensor("mag", "normalised")},
    }
    cal = calibration_of_what_ran(artifacts)
    assert set(cal) >= {"acc", "mag", "missing", "format_version"}
    assert "gyr" not in cal
    assert cal["missing"] == {"gyr": "gyr did not run: gyr_scale did not run: phases clipped"}
    complete = calibration_of_what_ran(
        {**artifacts, "gyr": {"calibration": _sensor("gyr", "rad/s")}}
    )
    assert "missing" not in complete and set(complete) >= {"acc", "gyr", "mag"}


def test_stage_listing_is_what_ran():
    notes = {"cube": "cube: automatic segmentation failed (cube: found 1 position); static poses"}
    rows = full_protocol_stages(
        {"rotation3d", "cube", "static"},
        has_reference=False,
        artifacts={"acc_cube": not_run_record("acc_cube", "no position segment"), "mag_step1": {}},
        notes=notes,
    )
    by = {r["stage"]: r for r in rows}
    assert by["acc_cube"]["status"] == "skipped"
    assert "no position segment" in by["acc_cube"]["reason"]
    assert "found 1 position" in by["acc_cube"]["reason"]
    assert by["mag_step1"]["status"] == "run"


KEYS = [("s", "gyr", ax, "all", "resid_rms") for ax in "xyz"]


def test_a_candidate_whose_replica_cannot_be_calibrated_does_not_fit():
    """The first candidate's replicas fail (ValueError): it is noted and not evaluated, and the
    selection goes on to the candidate that closes the gap."""
    rng = np.random.default_rng(0)
    null = NullModel.from_values(KEYS, rng.normal(0, 0.01, (20, 3)))
    stats = {h: {k: float(np.exp(0.5)) for k in KEYS} for h in (None, "A", "B")}
    broken = Candidate("broken", {"p": 1}, {"p": 1}, 1.0, 10.0)
    good = Candidate("good", {"p": 1}, {"p": 1}, 1.0, 10.0)

    def shifts_of(c):
        if c.name == "broken":
            raise ValueError("mag samples do not describe an ellipsoid")
        shift = {k: (0.5, 0.0) for k in KEYS}
        return shift, shift

    explained, *_ = select_forward(
        [broken, good], stats, null, null, shifts_of,
        alpha=0.05, min_heldout_shrink=0.3, detect_z=4.0,
    )  # fmt: skip
    assert explained == ["good"]
    assert not broken.accepted and not broken.evaluated
    assert "cannot be calibrated (mag samples do not describe an ellipsoid)" in broken.note


def test_a_session_clipped_in_every_gyro_motion_is_diagnosed_and_noted_as_saturation(tmp_path):
    """A gyro range of 45 deg/s clips the rotation3d phases and every rate-table run: no gyro
    scale can be fitted and the full twin cannot be built, yet the diagnosis ends, on the
    static recording, with the reason and 'saturation' noted from the readings."""
    from imucal.constants import IMU_RECORDINGS
    from imucal.gap import DiagnosisSettings, diagnose
    from imucal.ingest import ingest_recording
    from imucal.io.dataset import read_dataset
    from imucal.pipeline.full import PipelineOptions
    from imucal.sim import ProtocolConfig, make_truth, simulate_session, write_session
    from imucal.sim.effects import make_effect, stream_rng

    truth = make_truth("random", stream_rng(6, "truth"))
    session = simulate_session(
        truth, 7, ProtocolConfig(static_s=30.0), (make_effect("saturation", gyr=2950),)
    )
    info = read_dataset(write_session(session, tmp_path / "clipped"))
    imu = {
        r: ingest_recording(p, r, info, "test")[0]
        for r, p in info.recordings.items()
        if r in IMU_RECORDINGS
    }
    options = PipelineOptions.of_dataset(info)
    result = diagnose(imu, None, options, dataset="clipped", settings=DiagnosisSettings(replicas=5))
    assert "the calibration chain stopped" in result["fallback"]
    assert result["noted"] == ["saturation"]
    assert set(result["saturation"]["clip_fraction"]) == {"gyr"}
    # named from the clipped readings, so not listed as unobservable by the fallback's scope
    assert "saturation" not in result["not_observable"]


def test_backward_pass_drops_an_effect_a_later_one_explains():
    """'early' closes location 0 only; 'late' closes locations 0 and 1. Accepted in that
    order, 'early' closes nothing once 'late' is in the twin: it is dropped and reported as
    confusable with 'late'. Two effects on disjoint locations are both kept."""
    from imucal.gap.attribution import confusable, prune_backward

    keys = [("s", "gyr", ax, "all", "resid_rms") for ax in "xyzw"[:3]]
    rng = np.random.default_rng(1)
    null = NullModel.from_values(keys, rng.normal(0, 0.01, (20, 3)))
    stats = {"B": {k: float(np.exp(v)) for k, v in zip(keys, (0.5, 0.5, 0.0))}}

    def cand(name, closes):
        c = Candidate(name, {"p": 1}, {"p": 1}, 1.0, 10.0, accepted=True)
        c.shift_b = {keys[i]: (0.5, 0.0) for i in closes}
        return c

    early, late = cand("early", [0]), cand("late", [0, 1])
    explained, pruned = prune_backward([early, late], ["early", "late"], stats, null, 0.3)
    assert explained == ["late"]
    assert not early.accepted and "confusable with them" in early.note
    assert confusable(pruned, explained, 0.3)[0]["rivals"] == ["early"]

    a, b = cand("a", [0]), cand("b", [1])
    assert prune_backward([a, b], ["a", "b"], stats, null, 0.3) == (["a", "b"], [])
