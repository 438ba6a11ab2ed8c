"""Declared orientation references (imucal.io.orientation): conventions, gaps and bad input."""

from __future__ import annotations

import h5py
import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

from imucal.columns import POSITION, QUAT, TIME
from imucal.ingest import ingest_orientation_reference
from imucal.io.dataset import read_dataset
from imucal.io.readers import DeclarationError

N = 50
ROT = Rotation.random(N, random_state=4)
WXYZ = ROT.as_quat()[:, [3, 0, 1, 2]]


def write(tmp_path, reference: dict, recording_extra: dict | None = None):
    recording = {
        "reader": "hdf5",
        "file": "imu.h5",
        "rate_hz": 100.0,
        "columns": {f"gyr_{a}": ["gyr", k] for k, a in enumerate("xyz")},
        "units": {"gyr": "rad/s"},
        "reference": reference,
        **(recording_extra or {}),
    }
    cfg = {"name": "t", "gravity_m_s2": 9.81, "recordings": {"poses": recording}}
    (tmp_path / "dataset.yaml").write_text(yaml.safe_dump(cfg, sort_keys=False))
    return read_dataset(tmp_path)


@pytest.fixture
def files(tmp_path):
    gaps = WXYZ.copy()
    gaps[10:13] = np.nan
    with h5py.File(tmp_path / "imu.h5", "w") as f:
        f["gyr"] = np.zeros((N, 3))
        f["quat_wxyz"] = gaps
        f["quat_xyzw"] = gaps[:, [1, 2, 3, 0]].T  # 4 x N
        f["matrix"] = ROT.as_matrix().reshape(N, 9)
        f["mocap_t"] = 0.5 + np.arange(N) / 120.0
    return tmp_path


def quaternion(array: str, scalar: str, **extra) -> dict:
    return {
        "reader": "hdf5",
        "file": "imu.h5",
        "orientation": "quaternion",
        "scalar": scalar,
        "rotates": "body_to_world",
        "up": "+z",
        "columns": {f"q_{k}": [array, k] for k in range(4)},
        **extra,
    }


def same_rotation(a: np.ndarray, b: np.ndarray) -> None:
    np.testing.assert_allclose(np.abs(np.sum(a * b, axis=1)), 1.0, atol=1e-12)


def test_scalar_first_last_and_gaps_kept(files):
    for array, scalar in (("quat_wxyz", "first"), ("quat_xyzw", "last")):
        ds = write(files, quaternion(array, scalar, rate_hz=120.0))
        table, meta = ingest_orientation_reference("poses", ds, "test")
        assert list(table.columns) == [TIME, *QUAT]
        np.testing.assert_allclose(table[TIME], np.arange(N) / 120.0)
        q = table[list(QUAT)].to_numpy()
        assert np.isnan(q[10:13]).all() and meta["gap_rows"] == 3
        keep = np.isfinite(q).all(axis=1)
        same_rotation(q[keep], WXYZ[keep])
        assert meta["held_out"] is False and meta["up"] == "+z"


def test_a_declared_position_is_read_in_metres_with_the_gaps(files):
    where = np.linspace([0.1, -0.2, 1.0], [0.6, 0.3, 1.4], N)
    with h5py.File(files / "imu.h5", "a") as f:
        f["pos"] = where
        f["pos_mm"] = where * 1000.0
        f["pos_nan"] = np.full((N, 3), np.nan)
    position = {f"p_{a}": ["pos", k] for k, a in enumerate("xyz")}
    ref = quaternion("quat_wxyz", "first", rate_hz=120.0)
    ref["columns"] = {**ref["columns"], **position}
    table, meta = ingest_orientation_reference("poses", write(files, ref), "test")
    assert list(table.columns) == [TIME, *QUAT, *POSITION] and meta["position"] is True
    p = table[list(POSITION)].to_numpy()
    assert np.isnan(p[10:13]).all()  # the orientation's gaps are the position's
    keep = np.isfinite(p).all(axis=1)
    np.testing.assert_array_equal(p[keep], where[keep])
    # without it, no position columns
    table, meta = ingest_orientation_reference("poses", write(files, quaternion(
        "quat_wxyz", "first", rate_hz=120.0)), "test")  # fmt: skip
    assert list(table.columns) == [TIME, *QUAT] and meta["position"] is False
    bad = dict(ref, columns={**ref["columns"], **{f"p_{a}": ["pos_mm", k] for k, a in
                                                  enumerate("xyz")}})  # fmt: skip
    with pytest.raises(DeclarationError, match=r"reference.columns: .*imu.h5, sample 50 "
                       r"\(counted from 1\) has \|p\| = 1552.42; expected positions in metres"):  # fmt: skip
        ingest_orientation_reference("poses", write(files, bad), "test")
    partial = dict(ref, columns={k: v for k, v in ref["columns"].items() if k != "p_z"})
    with pytest.raises(DeclarationError, match=r"position targets \['p_x', 'p_y'\]; expected "
                       r"all three of p_x, p_y, p_z"):  # fmt: skip
        ingest_orientation_reference("poses", write(files, partial), "test")
    empty = dict(ref, columns={**ref["columns"], **{f"p_{a}": ["pos_nan", k] for k, a in
                                                    enumerate("xyz")}})  # fmt: skip
    with pytest.raises(DeclarationError, match=r"no finite position p_x, p_y, p_z"):
        ingest_orientation_reference("poses", write(files, empty), "test")


def test_matrix_own_time_base_and_world_to_body(files):
    ref = {
        "reader": "hdf5",
        "file": "imu.h5",
        "orientation": "matrix",
        "rotates": "world_to_body",
        "up": "+y",
        "held_out": True,
        "columns": {"t_s": "mocap_t", **{f"r_{i}{j}": ["matrix", 3 * (i - 1) + (j - 1)]
                                          for i in (1, 2, 3) for j in (1, 2, 3)}},
    }  # fmt: skip
    table, meta = ingest_orientation_reference("poses", write(files, ref), "test")
    np.testing.assert_allclose(table[TIME], 0.5 + np.arange(N) / 120.0)
    inverse = ROT.inv().as_quat()[:, [3, 0, 1, 2]]
    same_rotation(table[list(QUAT)].to_numpy(), inverse)
    assert meta["held_out"] is True and meta["orientation"] == "matrix"


def test_bad_declarations_name_the_key(files):
    with h5py.File(files / "imu.h5", "a") as f:
        bad = WXYZ.copy()
        bad[7] *= 0.9
        f["quat_bad"] = bad
    ds = write(files, quaternion("quat_bad", "first", rate_hz=120.0))
    with pytest.raises(DeclarationError, match=r"recordings.poses.reference.columns: .*imu.h5, "
                       r"sample 8 \(counted from 1\) has \|q\| = 0.9; expected unit quaternions"):  # fmt: skip
        ingest_orientation_reference("poses", ds, "test")
    ds = write(files, {**quaternion("quat_wxyz", "first", rate_hz=120.0), "orientation": "matrix"})
    with pytest.raises(DeclarationError, match=r"reference.scalar: scalar with a matrix"):
        ingest_orientation_reference("poses", ds, "test")
    no_rate = quaternion("quat_wxyz", "first")
    with pytest.raises(DeclarationError, match=r"reference.rate_hz: no t_s column and no rate_hz"):
        ingest_orientation_reference("poses", write(files, no_rate), "test")
    with pytest.raises(ValueError, match=r"key 'recordings/poses/reference': 'up' is a required"):
        write(files, {k: v for k, v in quaternion("quat_wxyz", "first").items() if k != "up"})
    cfg = {"name": "t", "gravity_m_s2": 9.81, "recordings": {"poses": {
            "parts": [{"reader": "hdf5", "file": "imu.h5", "rate_hz": 100.0,
                       "columns": {f"gyr_{a}": ["gyr", k] for k, a in enumerate("xyz")},
                       "units": {"gyr": "rad/s"}}],
            "reference": quaternion("quat_wxyz", "first", rate_hz=120.0)}}}  # fmt: skip
    (files / "dataset.yaml").write_text(yaml.safe_dump(cfg))
    with pytest.raises(ValueError, match=r"recordings.poses.reference: beside parts"):
        read_dataset(files)


def test_a_bad_row_of_a_text_reference_is_named_by_its_file_line(files):
    """Errors in a text file name the 1-based line of the file (comment lines and the header
    counted), not the 0-based index of the data row."""
    q = WXYZ.copy()
    q[7] *= 0.9  # data row 7 (from 0): line 11, after two comment lines and the header
    lines = ["# mocap export", "# 120 Hz", "t,qw,qx,qy,qz"]
    lines += [f"{i / 120:.6f}," + ",".join(f"{v:.9f}" for v in row) for i, row in enumerate(q)]
    (files / "mocap.csv").write_text("\n".join(lines) + "\n")
    ref = {"reader": "table", "file": "mocap.csv", "orientation": "quaternion", "scalar": "first",
           "rotates": "body_to_world", "up": "+z", "skip_lines": 2, "header": True,
           "columns": {"t_s": "t", "q_0": "qw", "q_1": "qx", "q_2": "qy", "q_3": "qz"}}  # fmt: skip
    with pytest.raises(DeclarationError, match=r"mocap.csv, line 11 has \|q\| = 0.9;"):
        ingest_orientation_reference("poses", write(files, ref), "test")


def test_tolerance_renormalises_and_untracked_rows_are_gaps(files):
    with h5py.File(files / "imu.h5", "a") as f:
        q = WXYZ.copy()
        q[7] *= 0.99736  # a Vicon sample rounded in the file
        q[20] = 0.0  # "not tracked" written as zeros
        q[21, 2] = np.nan  # one component lost
        q[22, 0] = np.inf
        f["quat_glitch"] = q
    ds = write(files, quaternion("quat_glitch", "first", rate_hz=120.0))
    table, meta = ingest_orientation_reference("poses", ds, "test")
    out = table[list(QUAT)].to_numpy()
    assert np.isnan(out[20:23]).all() and meta["gap_rows"] == 3
    np.testing.assert_allclose(np.linalg.norm(out[7]), 1.0, atol=1e-15)
    same_rotation(out[[7]], WXYZ[[7]])
    # the default is the schema's, and it is written into the metadata
    schema = read_dataset.__globals__["_validator"]().schema
    default = schema["$defs"]["orientation_reference"]["properties"]["unit_tolerance"]["default"]
    assert meta["unit_tolerance"] == default and meta["max_norm_error"] == pytest.approx(0.00264)
    strict = quaternion("quat_glitch", "first", rate_hz=120.0, unit_tolerance=1e-3)
    with pytest.raises(DeclarationError, match=r"imu.h5, sample 8 \(counted from 1\) has \|q\| = 0.99736; expected "
                       r"unit quaternions \(\| \|q\| - 1 \| <= .*reference.unit_tolerance = 0.001\)"):  # fmt: skip
        ingest_orientation_reference("poses", write(files, strict), "test")


def test_robot_poses_interpolated_component_wise_are_accepted(files):
    # robot poses at 10 Hz interpolated component by component to 120 Hz: norms below 1,
    # within the default tolerance
    poses = Rotation.from_rotvec(np.cumsum(np.full((6, 3), [0.05, -0.03, 0.04]), axis=0))
    wxyz = poses.as_quat()[:, [3, 0, 1, 2]]
    t = np.arange(N) / 120.0
    lerp = np.column_stack([np.interp(t, np.arange(6) / 10.0, wxyz[:, k]) for k in range(4)])
    assert 0.999 < np.linalg.norm(lerp, axis=1).min() < 1.0 - 1e-5
    with h5py.File(files / "imu.h5", "a") as f:
        f["quat_robot"] = lerp
    table, meta = ingest_orientation_reference(
        "poses", write(files, quaternion("quat_robot", "first", rate_hz=120.0)), "test"
    )
    assert meta["gap_rows"] == 0
    np.testing.assert_allclose(np.linalg.norm(table[list(QUAT)].to_numpy(), axis=1), 1.0)
