"""Ingest of the public recordings declared under data/real/ (skipped without ../shared)."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from imucal.columns import ACC, GYR, MAG, TIME
from imucal.ingest import ingest_recording, summarize_recording
from imucal.io.dataset import read_dataset
from imucal.segments.filtering import lowpass_recording

REPO = Path(__file__).resolve().parents[2]
REAL = REPO.parent / "shared" / "data" / "real"
DATASETS = REPO / "data" / "real"

# dataset, recording: rows, duration (s), effective rate (Hz), sensors, irregular
EXPECTED = {
    ("kyle_ak_imu_tk", "poses"): (51175, 511.7, 100.0, ["acc", "gyr"], False),
    ("mad_lab_ferraris", "ferraris"): (10376, 101.3, 102.4, ["acc", "gyr"], False),
    ("mad_lab_annotated", "ferraris"): (9414, 46.0, 204.8, ["acc", "gyr"], False),
    ("sunsided_sensor_fusion", "rotation3d"): (13676, 97.2, None, ["acc", "gyr", "mag"], True),
    ("sunsided_sensor_fusion", "static"): (115468, 655.1, None, ["acc", "gyr", "mag"], True),
    ("sunsided_sensor_fusion", "tumble"): (18718, 106.3, None, ["acc", "gyr", "mag"], True),
    ("tomisuarez2_imu", "poses"): (10245, 102.4, 100.0, ["acc", "gyr"], False),
    ("tomisuarez2_imu", "static"): (44930, 449.3, 100.0, ["acc", "gyr"], False),
    ("tomisuarez2_mag", "tumble"): (22745, 454.9, 50.0, ["mag"], False),
    ("ck_explorer", "poses"): (16000, 160.0, 100.0, ["acc"], False),
    ("ck_explorer", "tumble"): (12000, 120.0, 100.0, ["acc", "mag"], False),
    ("spluque_cats_thermal", "poses"): (268081, 268080.0, 1.0, ["acc", "gyr", "mag"], False),
}


@pytest.fixture(scope="module")
def real() -> Path:
    if not (REAL / "README.md").is_file():
        pytest.skip(f"public recordings not found at {REAL} (../shared is absent)")
    return REAL


def first_seconds(table, sensor: str, seconds: float) -> np.ndarray:
    cols = {"acc": ACC, "gyr": GYR, "mag": MAG}[sensor]
    part = table[table[TIME] < table[TIME].iloc[0] + seconds][list(cols)].dropna()
    return part.to_numpy()


@pytest.mark.parametrize(("name", "recording"), sorted(EXPECTED))
def test_real_recording_ingests(real, name, recording):
    dataset = read_dataset(DATASETS / name)
    assert all(p.is_file() for p in dataset.recording_files(recording))
    table, meta = ingest_recording(dataset.recordings[recording], recording, dataset, "test")
    summary = summarize_recording(table, meta)
    rows, duration, rate, sensors, irregular = EXPECTED[(name, recording)]
    assert summary["rows"] == rows
    assert summary["duration_s"] == pytest.approx(duration, abs=0.05)
    if rate is not None:
        assert summary["effective_rate_hz"] == pytest.approx(rate, rel=2e-3)
    assert summary["sensors"] == sensors and summary["irregular"] is irregular
    assert [c for c in table.columns if c[:4] in ("acc_", "gyr_", "mag_")] == [
        c for s in sensors for c in {"acc": ACC, "gyr": GYR, "mag": MAG}[s]
    ]
    assert all(f["sha256"] and Path(f["path"]).is_file() for f in meta["files"])
    assert summary["lost_packets"] is None  # none of them has a packet counter
    if "acc" in sensors:
        # specific force at rest or in slow hand motion: |acc| near g (uncalibrated: +-12 %)
        norm = np.linalg.norm(table[list(ACC)].dropna().to_numpy(), axis=1)
        assert np.median(norm) == pytest.approx(9.81, rel=0.12)
    if "mag" in sensors:
        # normalised to the assumed 50 uT; hard iron and the unknown local field: 0.5..1.5
        norm = np.linalg.norm(table[list(MAG)].dropna().to_numpy(), axis=1)
        assert 0.5 < np.median(norm) < 1.5


def test_real_static_parts_read_about_one_g(real):
    # the first 30 s of these recordings are static
    for name, recording in [("kyle_ak_imu_tk", "poses"), ("tomisuarez2_imu", "static"),
                            ("sunsided_sensor_fusion", "static")]:  # fmt: skip
        dataset = read_dataset(DATASETS / name)
        table, _ = ingest_recording(dataset.recordings[recording], recording, dataset, "test")
        acc = first_seconds(table, "acc", 30.0)
        gyr = first_seconds(table, "gyr", 30.0)
        assert np.median(np.linalg.norm(acc, axis=1)) == pytest.approx(9.81, rel=0.1), name
        assert np.std(acc, axis=0).max() < 0.1, name  # static: noise only, m/s^2
        assert np.abs(np.median(gyr, axis=0)).max() < np.deg2rad(6), name  # only the bias


def test_sunsided_axes_make_a_right_handed_consistent_frame(real):
    """With the declared axes, d f / dt = -w x f holds during the single-axis rotations."""
    dataset = read_dataset(DATASETS / "sunsided_sensor_fusion")
    table, meta = ingest_recording(dataset.recordings["rotation3d"], "rotation3d", dataset, "test")
    assert [p["part"] for p in meta["parts"]] == [0, 1, 2]
    static, _ = ingest_recording(dataset.recordings["static"], "static", dataset, "test")
    bias = static[list(GYR)].median().to_numpy()
    both = table.dropna(subset=[ACC[0], GYR[0]])
    t = both[TIME].to_numpy()
    f = both[list(ACC)].to_numpy()
    w = both[list(GYR)].to_numpy()
    for p in meta["parts"]:
        sel = (t >= p["t_start_s"]) & (t <= p["t_end_s"])
        kernel = np.ones(25) / 25
        fs = np.column_stack([np.convolve(f[sel, k], kernel, "same") for k in range(3)])
        ws = np.column_stack([np.convolve(w[sel, k], kernel, "same") for k in range(3)])
        df = np.gradient(fs, t[sel], axis=0)
        pred = -np.cross(ws, fs)
        corr = np.sum(pred * df) / np.sqrt(np.sum(pred**2) * np.sum(df**2))
        if p["part"] < 2:  # about z (vertical) gravity hardly moves: no information
            assert corr > 0.6, p  # about -0.7 with the raw gyro signs
        turns = np.trapezoid(w[sel] - bias, t[sel], axis=0) / (2 * np.pi)
        # two turns; x and z counter-clockwise, y clockwise in this frame (the folder name says
        # "ccw around y pointing left": its sense was not defined against the acc frame)
        assert turns[p["part"]] == pytest.approx([2.0, -2.0, 2.0][p["part"]], abs=0.1)
    # each part is its own block of the low-pass (the gap between parts is 10 s)
    out = lowpass_recording(table, order=4, cutoff_hz=5.0)
    starts = [a for a, _ in out.attrs["lowpass"]["blocks"]]
    assert {p["start_row"] for p in meta["parts"]} <= set(starts)


def test_annotated_session_sections_from_part_column(real):
    dataset = read_dataset(DATASETS / "mad_lab_annotated")
    table, meta = ingest_recording(dataset.recordings["ferraris"], "ferraris", dataset, "test")
    labels = [s["label"] for s in meta["sections"]]
    assert labels == ["x_p", "x_a", "y_p", "y_a", "z_p", "z_a", "x_rot", "y_rot", "z_rot"]
    assert np.all(np.diff(table[TIME].to_numpy()) > 0)
    for s in meta["sections"][:6]:  # the face pointing up reads about +g on its axis
        part = table[(table[TIME] >= s["start_s"]) & (table[TIME] <= s["end_s"])]
        axis = "xyz".index(s["up"][1])
        sign = 1 if s["up"][0] == "+" else -1
        assert sign * part[ACC[axis]].median() == pytest.approx(9.81, rel=0.1), s["label"]


def test_cats_netcdf4_poses_temperature_and_units(real):
    """The CATS tag's netCDF4 file: CF time, mrad/s gyro, the temperature kept, three poses."""
    dataset = read_dataset(DATASETS / "spluque_cats_thermal")
    table, meta = ingest_recording(dataset.recordings["poses"], "poses", dataset, "test")
    assert meta["time_units"] == "seconds since 2021-09-20 08:52:00"
    assert meta["file_units"]["gyr_x"] == "mrad/s" and meta["source_units"]["gyr"] == "mrad/s"
    temp = table["temp_c"].to_numpy()
    assert (temp.min(), temp.max()) == pytest.approx((4.8, 27.8), abs=0.05)  # SOURCE.md
    t = table[TIME].to_numpy()
    poses = [s for s in dataset.segments if s["recording"] == "poses"]
    assert [s["label"] for s in poses] == ["pose_z", "pose_x", "pose_y"]
    for s in poses:
        part = table[(t >= s["start_s"]) & (t <= s["end_s"])]
        axis, sign = "xyz".index(s["up"][1]), 1 if s["up"][0] == "+" else -1
        # the declared up axis reads +g within the uncalibrated accelerometer's 7 % (SOURCE.md:
        # |a| 10.47 / 10.09 / 9.66 m/s^2)
        assert sign * part[ACC[axis]].median() == pytest.approx(9.81, rel=0.07), s["label"]
        # at rest: the gyro's median is a bias of a few mrad/s, far below the handling's rates
        assert np.abs(part[list(GYR)].median().to_numpy()).max() < 0.1, s["label"]


def test_a_fresh_clone_without_shared_fails_clearly(tmp_path):
    """The dataset.yaml paths are relative to the dataset folder; without ../shared: clear error."""
    clone = tmp_path / "x" / "repo"
    shutil.copytree(DATASETS / "ck_explorer", clone / "data" / "real" / "ck_explorer")
    dataset = read_dataset(clone / "data" / "real" / "ck_explorer")
    expected = tmp_path / "x" / "shared" / "data" / "real"
    assert str(dataset.recordings["poses"]).startswith(str(expected))
    with pytest.raises(FileNotFoundError, match=r"recordings.poses.file: .*/x/shared/data/real/"
                       r"CK-Explorer__Magnetometer-and-Accelerometer-Calibration/acc_log.csv not found"):  # fmt: skip
        ingest_recording(dataset.recordings["poses"], "poses", dataset, "test")
