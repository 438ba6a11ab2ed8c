"""Automatic segmentation: the data-driven static detector, and the conformance session's phases,
cube positions, rate-table runs and static recording; every refusal names what it found."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation

from imucal.columns import ACC, GYR, MAG, TIME
from imucal.dataset import read_dataset
from imucal.segmentation import (
    SEGMENT_COLUMNS,
    DetectorSettings,
    find_quiet_windows,
    find_static_intervals,
    segment_cube,
    segment_dataset,
    segment_ratetable,
    segment_rotation3d,
)

FS = 100.0
G = 9.81


# --- synthetic: one smooth turn about x between two static intervals -----------------------------


def synthetic_turn(sigma_gyr: float, sigma_acc: float, seed: int = 0):
    """10 s static, a 360-deg turn about x (1 s cosine ramps, 60 deg/s plateau), 10 s static.

    Returns t (n,), acc (n, 3), gyr (n, 3) and the true motion interval (s).
    """
    rng = np.random.default_rng(seed)
    ramp, rate = 1.0, np.radians(60.0)
    plateau = (2 * np.pi - rate * ramp) / rate  # a ramp pair turns rate * ramp
    t0, t1 = 10.0, 10.0 + 2 * ramp + plateau
    t = np.arange(0, t1 + 10.0, 1 / FS)
    w = np.zeros_like(t)
    up = (t >= t0) & (t < t0 + ramp)
    w[up] = rate * 0.5 * (1 - np.cos(np.pi * (t[up] - t0) / ramp))
    w[(t >= t0 + ramp) & (t < t1 - ramp)] = rate
    down = (t >= t1 - ramp) & (t < t1)
    w[down] = rate * 0.5 * (1 + np.cos(np.pi * (t[down] - (t1 - ramp)) / ramp))
    angle = np.concatenate(([0.0], np.cumsum((w[1:] + w[:-1]) / 2 / FS)))
    gravity = Rotation.from_rotvec(np.outer(-angle, [1, 0, 0])).apply([0, 0, G])
    gyr = np.outer(w, [1, 0, 0]) + [0.01, -0.02, 0.005] + rng.normal(0, sigma_gyr, (t.size, 3))
    acc = gravity + rng.normal(0, sigma_acc, (t.size, 3))
    return t, acc, gyr, (t0, t1)


@pytest.mark.parametrize("noise_scale", [1.0, 10.0])
def test_static_threshold_follows_the_noise(noise_scale):
    sigma_g, sigma_a = 0.0015 * noise_scale, 0.015 * noise_scale
    t, acc, gyr, (t0, t1) = synthetic_turn(sigma_g, sigma_a)
    window = 50
    _, noise = find_quiet_windows(gyr, window, 1e-6)
    # ~1000 quiet windows of 50 samples overlap: ~40 independent ones, each with relative std
    # sqrt(2/49) = 0.2 -> ~3 % on the median; 15 % is 5 of those
    np.testing.assert_allclose(noise, sigma_g**2, rtol=0.15)
    static = find_static_intervals(t, acc, gyr)
    assert len(static.intervals) == 2
    (a0, b0), (a1, b1) = static.intervals
    assert a0 == 0 and b1 == t.size
    # the turn starts and ends with a cosine ramp, w = rate pi^2 tau^2 / (4 ramp^2) near rest,
    # which reaches k sigma after tau = 2 ramp / pi sqrt(k sigma / rate). A window is moving
    # when its variance exceeds 2.3 sigma^2, i.e. once the rate reaches a few sigma; allowing
    # k = 10 gives 0.08 s (0.24 s at the larger noise). Motion is never called static earlier.
    lag = 2 * 1.0 / np.pi * np.sqrt(10 * sigma_g / np.radians(60))
    assert t0 - 0.05 <= t[b0] <= t0 + lag
    assert t1 - lag <= t[a1] <= t1 + 0.05
    np.testing.assert_allclose(
        static.rest_rad_s, [0.01, -0.02, 0.005], atol=5 * sigma_g / np.sqrt(1000)
    )

    table = segment_rotation3d_from_single_turn(t, acc, gyr)
    assert table == ("x", 1, 1)


def segment_rotation3d_from_single_turn(t, acc, gyr):
    """The single turn as a rotation3d phase, through the motion finder (no y, z phase)."""
    with pytest.raises(ValueError) as err:
        segment_rotation3d(t, acc, gyr)
    msg = str(err.value)
    assert "found full-turn phases about ['x']" in msg
    assert "about x +360 deg raw (+1.00 turns) at" in msg
    return ("x", 1, 1)


def test_no_static_interval_is_refused():
    t = np.arange(0, 20, 1 / FS)
    gyr = np.column_stack([np.sin(t), np.cos(2 * t), np.sin(3 * t)]) + np.random.default_rng(
        0
    ).normal(0, 1e-3, (t.size, 3))
    acc = np.tile([0, 0, G], (t.size, 1)) + np.random.default_rng(1).normal(0, 1e-2, (t.size, 3))
    with pytest.raises(ValueError, match=r"no static interval of at least 1.0 s in 20.0 s of data"):
        find_static_intervals(t, acc, gyr)


def test_settings_are_checked():
    with pytest.raises(ValueError, match=r"window_s = -1: expected a positive number"):
        DetectorSettings(window_s=-1)


# --- the conformance session ---------------------------------------------------------------------


@pytest.fixture(scope="module")
def session(conformance_dir):
    """The conformance recordings in SI units (counts x sensitivity), and the truth."""
    ds = read_dataset(conformance_dir)
    tables = {}
    for name in ("rotation3d", "cube", "ratetable", "static"):
        raw = pd.read_csv(ds.recordings[name])
        for sensor, cols in (("acc", ACC), ("gyr", GYR), ("mag", MAG)):
            raw[list(cols)] = raw[list(cols)] * ds.sensitivity[sensor]
        tables[name] = raw
    truth = json.loads((conformance_dir / "truth.json").read_text())
    segments = segment_dataset(tables, ratetable=ds.ratetable, manual=ds.segments)
    return ds, tables, truth, segments


def calibrated_gyr(session, name: str) -> np.ndarray:
    _, tables, truth, _ = session
    m, b = np.array(truth["gyr"]["matrix"]), np.array(truth["gyr"]["bias"])
    return (tables[name][list(GYR)].to_numpy() - b) @ m.T


def gyro_noise(session) -> float:
    """Gyro white noise (rad/s), from the static recording calibrated with the truth."""
    return float(np.std(calibrated_gyr(session, "static"), axis=0).max())


def test_table_layout(session):
    segments = session[3]
    assert tuple(segments.columns) == SEGMENT_COLUMNS
    assert segments["recording"].unique().tolist() == ["rotation3d", "cube", "ratetable", "static"]
    assert set(segments["kind"]) <= {"static", "phase", "transition", "position", "run"}
    assert (segments["end_index"] > segments["start_index"]).all()
    assert segments.dtypes["start_index"] == np.int64 and segments.dtypes["turns"] == float


def test_rotation3d_phases(session):
    _, tables, _, segments = session
    seg = segments[segments["recording"] == "rotation3d"]
    phases = seg[seg["kind"] == "phase"]
    assert phases["label"].tolist() == ["x", "y", "z"]
    assert phases["axis"].tolist() == ["x", "y", "z"]
    assert phases["sense"].tolist() == [-1, 1, 1]
    assert phases["turns"].tolist() == [-2.0, 2.0, 2.0]
    trans = seg[seg["kind"] == "transition"]
    assert trans["label"].tolist() == ["t01", "t02"]
    assert trans["axis"].tolist() == ["z", "z"] and trans["sense"].tolist() == [1, -1]
    # raw quarter turns read 1/1.14 short (gyro scale ~1.15)
    np.testing.assert_allclose(trans["turns"], [0.25 / 1.145, -0.25 / 1.145], rtol=0.02)
    assert seg["label"].tolist() == [
        "s01",
        "x",
        "s02",
        "t01",
        "s03",
        "y",
        "s04",
        "t02",
        "s05",
        "z",
        "s06",
    ]
    assert seg.iloc[0]["start_s"] == 0 and seg.iloc[0]["end_s"] > 11.5

    # with the true calibration, each phase integrates to its whole turns and nothing rotates in
    # the static intervals: angle noise is sigma sqrt(T dt) ~ 1e-4 turn; a motion edge missed by
    # the detector would show as a deficit; 1e-3 turn (0.36 deg) is 10 noise sigmas
    t = tables["rotation3d"][TIME].to_numpy()
    cal = calibrated_gyr(session, "rotation3d")
    sigma = gyro_noise(session)
    for row in seg.itertuples():
        a, b = row.start_index, row.end_index
        angle = np.trapezoid(cal[a - 1 : b + 1], t[a - 1 : b + 1], axis=0) / (2 * np.pi)
        if row.kind == "static":
            mean = cal[a:b].mean(axis=0)
            assert np.all(np.abs(mean) < 5 * sigma / np.sqrt(b - a)), (row.label, mean)
        else:
            expected = np.zeros(3)
            expected["xyz".index(row.axis)] = row.turns if row.kind == "phase" else 0.25 * row.sense
            np.testing.assert_allclose(angle, expected, atol=1e-3, err_msg=row.label)


def test_cube_positions(session):
    ds, tables, truth, segments = session
    seg = segments[segments["recording"] == "cube"]
    positions = seg[seg["kind"] == "position"]
    assert positions["label"].tolist() == [f"p{i:02d}" for i in range(1, 13)]
    assert positions["start_s"].is_monotonic_increasing
    # the first interval repeats p01's gravity direction (a yaw before p01): kept as static
    assert seg[seg["kind"] == "static"]["label"].tolist() == ["s01"]
    acc = tables["cube"][list(ACC)].to_numpy()
    m, b = np.array(truth["acc"]["matrix"]), np.array(truth["acc"]["bias"])
    ups = []
    for row in positions.itertuples():
        cal = (acc[row.start_index : row.end_index] - b) @ m.T
        # every sample is at rest: |a| = g within the noise (~0.015 m/s^2 per axis, 6 sigma)
        assert np.abs(np.linalg.norm(cal, axis=1) - ds.gravity_m_s2).max() < 0.1, row.label
        ups.append(cal.mean(axis=0) / ds.gravity_m_s2)
    angles = np.degrees(np.arccos(np.clip(np.array(ups) @ np.array(ups).T, -1, 1)))
    assert angles[~np.eye(12, dtype=bool)].min() > 40  # 12 distinct orientations, >= 45 deg apart


def test_ratetable_runs(session):
    ds, _, _, segments = session
    runs = segments[segments["recording"] == "ratetable"]
    expected = [(ax, r) for ax in ds.ratetable["axes"] for r in ds.ratetable["rates_dps"]]
    assert runs["label"].tolist() == [f"{ax}{r:+d}" for ax, r in expected]
    assert runs["rate_dps"].tolist() == [float(r) for _, r in expected]
    assert runs["axis"].tolist() == [ax for ax, _ in expected]
    cal = np.degrees(calibrated_gyr(session, "ratetable"))
    sigma = np.degrees(gyro_noise(session))
    for row in runs.itertuples():
        true = np.zeros(3)
        true["xyz".index(row.axis)] = row.rate_dps
        part = cal[row.start_index : row.end_index]
        assert row.end_s - row.start_s > 7.0, row.label  # the steady part of an ~8 s plateau
        # steady only: the mean is the nominal rate within 5 sigma of an n-sample mean; at the
        # ends a ramp residue of a few sigma is below what a variance test can see (threshold
        # 2.3 sigma^2 over a window), so the first and last 0.1 s are within 3 sigma, no more
        np.testing.assert_allclose(
            part.mean(axis=0), true, atol=5 * sigma / np.sqrt(len(part)), err_msg=row.label
        )
        for edge in (part[:10], part[-10:]):
            np.testing.assert_allclose(edge.mean(axis=0), true, atol=3 * sigma, err_msg=row.label)


def test_static_recording(session):
    _, tables, _, segments = session
    seg = segments[segments["recording"] == "static"]
    assert seg["label"].tolist() == ["s01"] and seg["kind"].tolist() == ["static"]
    assert seg.iloc[0]["start_index"] == 0 and seg.iloc[0]["end_index"] == len(tables["static"])


def cut(table: pd.DataFrame, t_max: float) -> tuple[np.ndarray, ...]:
    part = table[table[TIME] < t_max]
    return part[TIME].to_numpy(), part[list(ACC)].to_numpy(), part[list(GYR)].to_numpy()


def test_missing_phase_is_refused(session):
    t, acc, gyr = cut(session[1]["rotation3d"], 62.0)  # stops before phase z
    with pytest.raises(ValueError) as err:
        segment_rotation3d(t, acc, gyr)
    msg = str(err.value)
    assert "expected one full-turn phase about x, then y, then z" in msg
    assert "found full-turn phases about ['x', 'y']" in msg
    assert "about z +79 deg raw (+0.22 turns) at 31." in msg  # the transitions are listed


def test_too_few_positions_are_refused(session):
    t, acc, gyr = cut(session[1]["cube"], 76.0)  # p01..p07
    with pytest.raises(
        ValueError,
        match=r"cube: found 7 static position\(s\) \(0.0-14.0 s, .*\); "
        r"the cube fit needs at least 9 \(the protocol has 12\)",
    ):
        segment_cube(t, acc, gyr)


def test_wrong_run_count_is_refused(session):
    ds = session[0]
    t, acc, gyr = cut(session[1]["ratetable"], 293.0)  # z+200 .. z+400 missing
    with pytest.raises(
        ValueError,
        match=r"ratetable: found 21 constant-rate run\(s\) of at least 50 "
        r"deg/s; expected 24 non-zero runs .* runs found: about x -345 deg/s raw at 7.0",
    ):
        segment_ratetable(t, acc, gyr, ds.ratetable["axes"], ds.ratetable["rates_dps"])


def test_run_order_mismatch_is_refused(session):
    ds = session[0]
    table = session[1]["ratetable"]
    t, acc, gyr = table[TIME].to_numpy(), table[list(ACC)].to_numpy(), table[list(GYR)].to_numpy()
    with pytest.raises(
        ValueError, match=r"run at 7.0-15.0 s is about x at -345 deg/s raw; expected y -400"
    ):
        segment_ratetable(t, acc, gyr, ["y", "x", "z"], ds.ratetable["rates_dps"])


def test_manual_override_replaces_one_recording(session):
    ds, tables, _, automatic = session
    manual = [
        {"recording": "static", "label": "s01", "kind": "static", "start_s": 10.0, "end_s": 20.0},
    ]
    segments = segment_dataset(tables, ratetable=ds.ratetable, manual=manual)
    row = segments[segments["recording"] == "static"].iloc[0]
    t = tables["static"][TIME].to_numpy()
    assert (row["start_index"], row["end_index"]) == (1000, 2001)
    assert t[row["start_index"]] >= 10.0 and t[row["end_index"] - 1] <= 20.0
    others = segments[segments["recording"] != "static"].reset_index(drop=True)
    pd.testing.assert_frame_equal(
        others, automatic[automatic["recording"] != "static"].reset_index(drop=True)
    )
    bad = [dict(manual[0], start_s=20.0, end_s=10.0)]
    with pytest.raises(ValueError, match=r"manual segment static/s01: 20.0-10.0 s holds 0 sample"):
        segment_dataset(tables, ratetable=ds.ratetable, manual=bad)


# --- the project's simulator: true boundaries -----------------------------------------------------


@pytest.mark.parametrize("effects", [(), ("packet_loss", "timing_jitter", "temperature_drift")])
def test_simulated_session_boundaries(tmp_path, effects):
    """Labels, kinds, axes, senses and whole turns as simulated; boundaries within 0.2 s.

    The simulator's motions start and end with cosine ramps; the detector sees a motion once
    its rate is a few noise sigmas (see test_static_threshold_follows_the_noise), ~0.1 s in.
    """
    from imucal.ingest import ingest_recording
    from imucal.sim import parse_effect, simulate

    session = simulate(
        tmp_path / "sim",
        preset="paper",
        seed=3,
        static_s=60.0,
        effects=tuple(parse_effect(e) for e in effects),
    )
    ds = read_dataset(tmp_path / "sim")
    tables = {
        name: ingest_recording(
            ds.recordings[name], recording=name, dataset=ds, imucal_version="test"
        )[0]
        for name in ("rotation3d", "cube", "ratetable", "static")
    }
    found = segment_dataset(tables, ratetable=ds.ratetable, manual=ds.segments)
    truth = pd.DataFrame([s.to_dict() for plan in session.plans.values() for s in plan.segments])
    both = truth.merge(found, on=["recording", "label"], how="left", suffixes=("_true", ""))
    assert both["kind"].tolist() == both["kind_true"].tolist()
    assert np.abs(both["start_s"] - both["start_s_true"]).max() < 0.2
    assert np.abs(both["end_s"] - both["end_s_true"]).max() < 0.2
    rot = both[both["kind_true"].isin(["phase", "transition", "run"]) & (both["sense_true"] != 0)]
    assert rot["axis"].tolist() == rot["axis_true"].tolist()
    assert rot["sense"].tolist() == rot["sense_true"].tolist()
    phases = both[both["kind_true"] == "phase"]
    assert phases["turns"].tolist() == phases["turns_true"].tolist()


# --- partial protocols: static poses, fallback ------------------------------------------------


def test_poses_are_the_static_intervals_with_and_without_a_gyro():
    t, acc, gyr, (t0, t1) = synthetic_turn(0.002, 0.01)
    table = pd.DataFrame({TIME: t, **dict(zip(ACC, acc.T)), **dict(zip(GYR, gyr.T))})
    both = segment_dataset({"poses": table})
    assert both["label"].tolist() == ["s01", "s02"] and set(both["kind"]) == {"static"}
    assert both.iloc[0]["end_s"] <= t0 + 0.5 and both.iloc[1]["start_s"] >= t1 - 0.5
    # an accelerometer-only logger: quiet means a quiet accelerometer
    acc_only = segment_dataset({"poses": table.drop(columns=list(GYR))})
    assert acc_only["label"].tolist() == ["s01", "s02"]
    # a magnetometer-only recording has no poses to tell
    mag_only = pd.DataFrame({TIME: t, **dict(zip(MAG, acc.T / G))})
    assert segment_dataset({"tumble": mag_only}).empty


def test_fallback_keeps_static_poses_and_says_why(session):
    t, acc, gyr = cut(session[1]["rotation3d"], 62.0)  # stops before phase z
    table = pd.DataFrame({TIME: t, **dict(zip(ACC, acc.T)), **dict(zip(GYR, gyr.T))})
    with pytest.raises(ValueError, match="full-turn phase"):
        segment_dataset({"rotation3d": table})
    segments = segment_dataset({"rotation3d": table}, fallback=True)
    assert set(segments["kind"]) == {"static"} and len(segments) >= 2
    assert "automatic segmentation failed" in segments.attrs["notes"]["rotation3d"]
