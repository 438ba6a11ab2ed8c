"""The gap diagnosis of a session of static poses (imucal.gap.poses)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from imucal.columns import ACC, GYR, TIME
from imucal.gap import DiagnosisSettings
from imucal.gap.poses import diagnose_poses, longest_pose
from imucal.io.dataset import read_dataset
from imucal.segments.table import segment_row, segments_frame

RATE_HZ = 10.0
GYR_PER_K = 2e-3  # rad/s per K on every gyro axis: far above the noise over a 20 K sweep


def poses_session(rng: np.random.Generator, per_k: float) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Three static poses of 1500, 4000 and 2500 samples at 10 Hz, each warming up by 15 K
    (time constant 100 s, the simulator's warm-up model); the gyro drifts ``per_k`` rad/s
    per K."""
    lengths, parts, rows, start = (1500, 4000, 2500), [], [], 0
    for k, n in enumerate(lengths):
        warm = 1.0 - np.exp(-np.arange(n) / RATE_HZ / 100.0)
        temp = 10.0 + 15.0 * warm + 0.01 * rng.standard_normal(n)
        acc = np.tile(9.81 * np.eye(3)[k], (n, 1)) + 0.01 * rng.standard_normal((n, 3))
        gyr = 0.01 + per_k * (temp - 20.0)[:, None] + 1e-3 * rng.standard_normal((n, 3))
        parts.append(np.column_stack([acc, gyr, temp]))
        rows.append((f"pose_{k}", start, start + n))
        start += n
    data = np.vstack(parts)
    t = np.arange(len(data)) / RATE_HZ
    table = pd.DataFrame({TIME: t, **dict(zip((*ACC, *GYR, "temp_c"), data.T))})
    segments = segments_frame(
        [segment_row("poses", label, "position", t, a, b) for label, a, b in rows]
    )
    return table, segments


def test_the_longest_pose_after_its_settling_time():
    table, segments = poses_session(np.random.default_rng(0), 0.0)
    pose, info = longest_pose(table, segments, recording="poses", settle_s=50.0)
    assert info["label"] == "pose_1" and info["poses"] == 3
    assert len(pose) == 4000 - 500  # 50 s at 10 Hz left out
    assert info["start_s"] == pytest.approx(150.0 + 50.0) and info["end_s"] == pytest.approx(549.9)
    with pytest.raises(ValueError, match=r"recording 'cube' has no static pose"):
        longest_pose(table, segments, recording="cube", settle_s=0.0)


@pytest.mark.parametrize(("per_k", "named"), [(GYR_PER_K, True), (0.0, False)])
def test_a_drift_with_temperature_is_named_and_a_clean_session_is_not(per_k, named):
    table, segments = poses_session(np.random.default_rng(4), per_k)
    result = diagnose_poses(
        table, segments, recording="poses", settle_s=0.0, dataset="t", calibration=None,
        sensitivity={}, gravity_m_s2=9.81, settings=DiagnosisSettings(replicas=10),
    )  # fmt: skip
    assert result["scope"] == "poses" and result["pose"]["label"] == "pose_1"
    assert ("temperature_drift" in result["explained"]) is named
    if named:
        drift = next(e for e in result["effects"] if e["name"] == "temperature_drift")
        assert drift["params"]["gyr_per_k"] == pytest.approx([GYR_PER_K] * 3, rel=0.05)


REAL = Path(__file__).resolve().parents[3] / "shared" / "data" / "real"
CATS = Path(__file__).resolve().parents[2] / "data" / "real" / "spluque_cats_thermal"


def test_cats_tag_gets_a_scope_and_its_temperature_drift_named():
    if not (REAL / "spluque__scikit-diveMove" / "cats_temperature_calib.nc").is_file():
        pytest.skip(f"the CATS recording is not at {REAL} (../shared is absent)")
    from imucal.ingest import ingest_recording
    from imucal.segments.segmentation import segment_dataset

    dataset = read_dataset(CATS)
    table, _ = ingest_recording(dataset.recordings["poses"], "poses", dataset, "test")
    segments = segment_dataset({"poses": table}, manual=dataset.segments)
    result = diagnose_poses(
        table, segments, recording="poses", settle_s=3600.0, dataset="cats", calibration=None,
        sensitivity={}, gravity_m_s2=9.81, settings=DiagnosisSettings(replicas=5),
    )  # fmt: skip
    assert result["scope"] == "poses" and result["pose"]["label"] == "pose_z"
    assert "temperature_drift" in result["explained"]
