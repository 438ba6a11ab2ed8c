"""The gap diagnosis of recordings with an orientation reference (imucal.gap.motion), on simulated
sessions: a clean one has no gap, a planted gyroscope g-sensitivity is found, estimated and
explained; with a static recording beside them both parts are scored in one diagnosis."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation

from imucal import errormodel
from imucal.calibration import SensorCalibration
from imucal.columns import GYR, QUAT, SEGMENT_COLUMNS, SENSOR_COLUMNS, TIME
from imucal.gap import DiagnosisSettings
from imucal.gap.composite import diagnose_partial_session
from imucal.gap.motion import motion_part, reference_part
from imucal.gap.motionstats import motion_statistics
from imucal.gap.statictwin import StaticTwin, render_static
from imucal.sim import make_truth
from imucal.sim.effects import stream_rng
from imucal.sim.orientation import simulate_orientation_session
from imucal.sim.session import SENSITIVITY

MATRIX = errormodel.compose([1.02, 0.98, 1.01], [0.004, -0.003, 0.005], [0.0, 0.0, 0.0])
BIAS = np.array([0.01, -0.02, 0.015])
MOUNTING = Rotation.from_rotvec([0.3, -0.2, 0.8]).as_matrix()
#: Planted g-sensitivity of the raw reading, rad/s per m/s^2 (about 0.5 deg/s per g on the
#: diagonal: a poor MEMS gyroscope; cross-axis terms of either sign).
G_SENSITIVITY = np.array([[1.0e-3, 2.0e-4, -1.5e-4], [-2.5e-4, -8.0e-4, 1.0e-4],
                          [1.2e-4, -2.0e-4, 6.0e-4]])  # fmt: skip
SETTINGS = DiagnosisSettings(replicas=12, seed=0, crn_seeds=3)


def session_inputs(seed: int, g_sensitivity: np.ndarray | None = None, jitter_s: float = 0.0):
    s = simulate_orientation_session(
        seed, matrix=MATRIX, bias=BIAS, mounting=MOUNTING, offset_s=0.3, duration_s=120.0,
        reference_jitter_s=jitter_s,
    )  # fmt: skip
    gyr = s.gyr.copy()
    if g_sensitivity is not None:
        gyr += s.acc @ g_sensitivity.T  # the accelerometer reads the true specific force in B
    table = pd.DataFrame({TIME: s.t_module, **dict(zip(GYR, gyr.T))})
    reference = pd.DataFrame({TIME: s.t_reference, **dict(zip(QUAT, s.quat_reference.T))})
    rests = [
        {"recording": "moves", "label": f"s{k + 1:02d}", "kind": "static", "start_s": lo,
         "end_s": hi, "start_index": 0, "end_index": 0, "axis": "", "rate_dps": np.nan,
         "sense": 0, "turns": np.nan, "up": "", "angle_deg": np.nan}
        for k, (lo, hi) in enumerate(s.rests_s)
    ]  # fmt: skip
    calibration = {"gyr": SensorCalibration("gyr", BIAS, MATRIX, "rad/s").to_dict()}
    motion = motion_part(
        {"moves": table},
        {"moves": (reference, {"up": "+z"})},
        calibration,
        pd.DataFrame(rests, columns=list(SEGMENT_COLUMNS)),
        {"moves": "d.yaml: recordings.moves.reference"},
        {},
        9.81,
        (1.0, 10.0),
    )
    return s, calibration, motion


def diagnose(calibration, motion, static=None):
    return diagnose_partial_session(
        static, motion=motion, dataset="sim", calibration=calibration, sensitivity={},
        gravity_m_s2=9.81, settings=SETTINGS,
    )  # fmt: skip


def test_the_reference_noise_is_measured_at_the_slowest_intervals():
    _, _, (_, twin) = session_inputs(4, jitter_s=3e-4)
    # the simulator's reference noise is 0.0005 rad per axis; the slowest quarter of the
    # intervals (8,500 of them) measures its rates' variance to about 2 % (1 % in the std),
    # and the jitter, growing with the rate, barely enters there
    assert twin.recordings["moves"].reference_noise_rad == pytest.approx(5e-4, rel=0.05)


def test_the_twin_replicates_a_clean_session():
    _, calibration, (recordings, twin) = session_inputs(5)
    recorded = motion_statistics(recordings, windows_s=twin.windows_s)
    replica = twin.replica(0).stats[None]
    assert set(replica) == set(recorded)
    for key, value in recorded.items():
        if key[4] == "resid_rms":  # noise-dominated: the twin's noise is the recording's
            assert replica[key] == pytest.approx(value, rel=0.1), key
    result = diagnose(calibration, (recordings, twin))
    assert result["scope"] == "reference"
    assert result["explained"] == []
    assert not result["gap"]["significant"], result["locations"][:3]
    assert "timing_jitter" in result["not_observable"]


def test_a_planted_g_sensitivity_is_found_and_explains_the_gap():
    _, calibration, motion = session_inputs(6, G_SENSITIVITY)
    result = diagnose(calibration, motion)
    assert result["gap"]["significant"]
    assert any(loc["statistic"] == "ref_g_slope" for loc in result["locations"])
    assert result["explained"][:1] == ["g_sensitivity"]
    found = next(e for e in result["effects"] if e["name"] == "g_sensitivity")
    estimate = np.array(found["params"]["matrix"])
    # G in frame B (the calibrated gyroscope's): the planted raw matrix seen through K
    true = MATRIX @ G_SENSITIVITY
    # per-element standard error: the gyroscope's noise over a reference interval, 0.01 rad/s /
    # sqrt(200 / 120) = 0.0077 rad/s, over 14,000 intervals and a specific force of about
    # 5.7 m/s^2 RMS per axis: 0.0077 / (sqrt(14000) 5.7) = 1.1e-5 (the reference's noise
    # enters its rates differenced, and a difference averages out against slowly turning
    # gravity); five of them bound the error
    assert np.abs(estimate - true).max() < 5.5e-5
    assert found["heldout_shrink"] > 0.5
    assert not result["remaining"]["significant"]


def test_a_planted_reference_jitter_is_found_and_explains_the_gap():
    # 0.3 ms at 2 rad/s RMS and 120 Hz: rate errors of 2 sqrt(2) 0.3 ms x 120 Hz = 0.1 rad/s
    # RMS, above the 0.085 rad/s of the reference's white noise
    _, calibration, motion = session_inputs(7, jitter_s=3e-4)
    result = diagnose(calibration, motion)
    assert result["gap"]["significant"]
    assert result["explained"][:1] == ["reference_jitter"]
    found = next(e for e in result["effects"] if e["name"] == "reference_jitter")
    # the slope of 43,000 squared residuals on omega^2: a few per cent
    assert found["params"]["std_s"] == pytest.approx(3e-4, rel=0.1)
    assert found["heldout_shrink"] > 0.5
    assert not result["remaining"]["significant"]


def static_recording(seed: int, duration_s: float = 120.0) -> pd.DataFrame:
    """An ingested static recording (acc/gyro at 100 Hz), rendered by the simulator."""
    truth = make_truth("paper", stream_rng(0, "truth"))
    twin = StaticTwin(truth, dict(SENSITIVITY), {"imu": (int(duration_s * 100) + 1, 100.0)})
    stream = render_static(twin, seed)["imu"]
    columns = {
        c: v[:, j] for s, v in stream.values.items() for j, c in enumerate(SENSOR_COLUMNS[s])
    }
    return pd.DataFrame({TIME: stream.t_s, **columns})


def test_a_static_recording_and_a_reference_are_scored_together():
    _, calibration, motion = session_inputs(6, G_SENSITIVITY)
    result = diagnose(calibration, motion, static=static_recording(3))
    assert result["scope"] == "static+reference"
    stages = {loc["stage"] for loc in result["all_locations"]}
    assert {"reference", "noise", "ingest"} <= stages
    assert set(result["twin"]) == {"static", "motion"}
    # the static part has nothing to show; the reference part's effect is found as alone
    assert result["explained"][:1] == ["g_sensitivity"]
    assert not any(loc["stage"] != "reference" for loc in result["locations"])
    # what neither part can show is listed once, with the reason of the part that cannot
    assert "g_sensitivity" not in result["not_observable"]
    assert "mag_latency" in result["not_observable"]


def test_a_reference_that_cannot_be_aligned_is_named_not_scored():
    s, calibration, _ = session_inputs(5)
    other = simulate_orientation_session(11, matrix=MATRIX, bias=BIAS, mounting=MOUNTING)
    table = pd.DataFrame({TIME: s.t_module, **dict(zip(GYR, s.gyr.T))})
    wrong = pd.DataFrame({TIME: other.t_reference, **dict(zip(QUAT, other.quat_reference.T))})
    part, reason = reference_part(
        tables={"moves": table}, references={"moves": (wrong, {"up": "+z"})},
        calibration=calibration, segments=pd.DataFrame(columns=list(SEGMENT_COLUMNS)),
        where={"moves": "d.yaml: recordings.moves.reference"}, sensitivity={}, gravity_m_s2=9.81,
    )  # fmt: skip
    assert part is None and "recordings.moves.reference" in reason
    result = diagnose_partial_session(
        None, motion=None, reference_not_scored=reason, dataset="sim", calibration=calibration,
        sensitivity={}, gravity_m_s2=9.81, settings=SETTINGS,
    )  # fmt: skip
    assert result["scope"] == "none" and result["reference_not_scored"] == reason
    assert "cannot be scored" in result["reason"]
    # a static recording beside it is still diagnosed, and the reference's reason is kept
    with_static = diagnose_partial_session(
        static_recording(3), motion=None, reference_not_scored=reason, dataset="sim",
        calibration=calibration, sensitivity={}, gravity_m_s2=9.81, settings=SETTINGS,
    )  # fmt: skip
    assert with_static["scope"] == "static" and with_static["reference_not_scored"] == reason
