"""Automatic segmentation: the data-driven static detector, and the conformance session's phases,
cube positions, rate-table runs and static recording; every refusal names what it found."""

from __future__ import annotations

import json
import re

import numpy as np
import pandas as pd
import pytest
from conftest import z_limit
from scipy.spatial.transform import Rotation

from imucal.columns import ACC, GYR, MAG, SEGMENT_COLUMNS, TIME
from imucal.io.dataset import read_dataset
from imucal.segments.detector import DetectorSettings, find_quiet_windows, find_static_intervals
from imucal.segments.protocol import segment_cube, segment_rotation3d
from imucal.segments.ratetable import segment_ratetable
from imucal.segments.segmentation import segment_dataset, short_rest_note
from imucal.segments.table import segments_frame
from imucal.sim.orientation import simulate_orientation_session

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
    assert segments.dtypes["start_index"] == np.int64 and segments.dtypes["turns"] == np.float64
    # rests and cube positions turn about no axis: no sense, no axis, no turns, no rate
    rests = segments[segments["kind"].isin(["static", "position"])]
    assert (rests["sense"] == 0).all() and (rests["axis"] == "").all()
    assert rests["turns"].isna().all() and rests["rate_dps"].isna().all()


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
    z = z_limit(3 * int(np.sum(seg["kind"] == "static")))  # every static mean, three axes
    for row in seg.itertuples():
        a, b = row.start_index, row.end_index
        angle = np.trapezoid(cal[a - 1 : b + 1], t[a - 1 : b + 1], axis=0) / (2 * np.pi)
        if row.kind == "static":
            mean = cal[a:b].mean(axis=0)
            assert np.all(np.abs(mean) < z * sigma / np.sqrt(b - a)), (row.label, mean)
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


# --- rate table: clipped runs, short plateaus, split plateaus -------------------------------------


def ingested(folder):
    """The IMU recordings of a simulated dataset folder, ingested (SI units)."""
    from imucal.ingest import ingest_recording

    ds = read_dataset(folder)
    names = ("rotation3d", "cube", "ratetable", "static")
    tables = {
        n: ingest_recording(ds.recordings[n], recording=n, dataset=ds, imucal_version="test")[0]
        for n in names
    }
    return ds, tables


def true_runs(folder) -> pd.DataFrame:
    segments = json.loads((folder / "truth.json").read_text())["segments"]
    return pd.DataFrame([s for s in segments if s["recording"] == "ratetable"])


def assert_runs_match_truth(found: pd.DataFrame, truth: pd.DataFrame, tol_s: float) -> None:
    """Labels, axes, senses in order, and plateau boundaries within ``tol_s`` of the truth."""
    both = truth.merge(found, on="label", how="left", suffixes=("_true", ""))
    assert found["label"].tolist() == truth["label"].tolist()
    assert both["axis"].tolist() == both["axis_true"].tolist()
    assert both["sense"].tolist() == both["sense_true"].tolist()
    assert np.abs(both["start_s"] - both["start_s_true"]).max() < tol_s
    assert np.abs(both["end_s"] - both["end_s_true"]).max() < tol_s


def test_saturated_ratetable_is_segmented_and_the_fit_leaves_clipped_runs_out(tmp_path):
    """The gyro range clips the +-300 and +-400 deg/s runs: they are still found, matched by the
    table order and nominal rate, named in the notes; the rate-table fit drops them and recovers
    the truth from the others."""
    from imucal.pipeline import stages
    from imucal.sim import parse_effect, simulate

    folder = tmp_path / "sat"
    simulate(folder, preset="paper", seed=3, effects=(parse_effect("saturation"),), static_s=20.0)
    ds, tables = ingested(folder)
    segments = segment_dataset(tables, ratetable=ds.ratetable)
    runs = segments[segments["recording"] == "ratetable"]
    # the ramps' clipped ends are cut off: boundaries as close as the unclipped runs' (0.2 s, the
    # tolerance of test_simulated_session_boundaries)
    assert_runs_match_truth(runs, true_runs(folder), tol_s=0.2)

    truth = json.loads((folder / "truth.json").read_text())
    limit = ds.range_counts["gyr"] * ds.sensitivity["gyr"]
    m_inv = np.linalg.inv(np.array(truth["gyr"]["matrix"]))
    raw = {  # raw = M^-1 w + b (the truth's model), noise-free
        row.label: m_inv @ (np.radians(row.rate_dps) * np.eye(3)["xyz".index(row.axis)])
        + truth["gyr"]["bias"]
        for row in runs.itertuples()
    }
    clipped = [label for label, r in raw.items() if np.abs(r).max() > limit]
    assert len(clipped) == 12  # every +-300 and +-400 deg/s run (scale ~1.15 x 250 deg/s range)
    note = segments.attrs["notes"]["ratetable"]
    assert f"run(s) {', '.join(clipped)} clipped at the gyroscope range" in note

    table, _ = stages.fit_gyr_table(tables["ratetable"], segments, saturation_limit_rad_s=limit)
    assert table["labels"] == [label for label in runs["label"] if label not in clipped]
    # 15 runs left (12 dof); the fit's std is the noise from its residuals: an error over it
    # is Student's t(12), bound for the 12 errors at 1e-4
    err_m = np.array(table["matrix"]) - truth["gyr"]["matrix"]
    err_b = np.array(table["bias"]) - truth["gyr"]["bias"]
    z = z_limit(12, dof=12)
    assert np.all(np.abs(err_m) < z * np.array(table["std_matrix"])), err_m
    assert np.all(np.abs(err_b) < z * np.array(table["std_bias"])), err_b


@pytest.mark.parametrize("plateau_s", [4.0, 2.5])
def test_short_plateaus_are_segmented_at_the_true_boundaries(tmp_path, plateau_s):
    """Plateaus of a few seconds (the blind check's 4 s and 1.5 s pauses) give one run each, at
    the simulator's plateau within 0.2 s (the detector sees the cosine ramp a few noise sigmas
    in, ~0.1 s), and no note (nothing clipped or split)."""
    from imucal.sim import ProtocolConfig, make_truth, simulate_session, write_session
    from imucal.sim.effects import stream_rng

    config = ProtocolConfig(run_plateau_s=plateau_s, run_pause_s=1.5, static_s=20.0)
    truth = make_truth("random", stream_rng(5, "truth"))
    folder = write_session(simulate_session(truth, 5, config), tmp_path / "short")
    ds, tables = ingested(folder)
    runs = segment_dataset({"ratetable": tables["ratetable"]}, ratetable=ds.ratetable)
    assert_runs_match_truth(runs, true_runs(folder), tol_s=0.2)
    assert runs.attrs["notes"] == {}


def test_a_plateau_split_by_a_disturbance_is_one_run(tmp_path):
    """A 0.1-s knock in the middle of a 4-s plateau leaves two quiet pieces of ~1.7 s, both of at
    least min_static_s; they read the same rate and the table did not stop between them: one run,
    the longer piece, inside the true plateau, and a note says so."""
    from imucal.sim import ProtocolConfig, make_truth, simulate_session, write_session
    from imucal.sim.effects import stream_rng

    config = ProtocolConfig(run_plateau_s=4.0, run_pause_s=1.5, static_s=20.0)
    folder = write_session(
        simulate_session(make_truth("random", stream_rng(5, "truth")), 5, config), tmp_path / "k"
    )
    ds, tables = ingested(folder)
    table = tables["ratetable"]
    truth = true_runs(folder).set_index("label")
    t = table[TIME].to_numpy()
    middle = (truth.loc["y+200", "start_s"] + truth.loc["y+200", "end_s"]) / 2
    knock = (t >= middle - 0.05) & (t < middle + 0.05)
    gyr = table[list(GYR)].to_numpy()
    gyr[knock] += np.random.default_rng(0).normal(0, 0.5, (int(knock.sum()), 3))  # 30 deg/s
    acc = table[list(ACC)].to_numpy()
    runs = segment_ratetable(t, acc, gyr, ds.ratetable["axes"], ds.ratetable["rates_dps"])
    assert runs["label"].tolist() == truth.index.tolist()
    row = runs.set_index("label").loc["y+200"]
    assert truth.loc["y+200", "start_s"] - 0.2 < row["start_s"] < row["end_s"]
    assert row["end_s"] < truth.loc["y+200", "end_s"] + 0.2
    assert row["end_s"] - row["start_s"] > 1.5  # a whole piece, not a fragment of the knock
    assert not (row["start_s"] < middle < row["end_s"])  # the knock is left out
    assert runs.attrs["notes"]["ratetable"].endswith(
        "run(s) y+200 interrupted by a disturbance: the longest quiet piece kept"
    )


def test_clipped_run_reading_above_its_nominal_rate_is_refused(session):
    """A clipped reading is a lower bound on the raw rate: it refutes a nominal rate it exceeds by
    more than the scale tolerance, and matches any larger one."""
    ds = session[0]
    table = session[1]["ratetable"]
    t, acc, gyr = table[TIME].to_numpy(), table[list(ACC)].to_numpy(), table[list(GYR)].to_numpy()
    gyr = gyr.copy()
    limit = np.radians(300.0)  # clip the conformance gyro at 300 deg/s: x-400 reads ~-345 raw
    gyr = np.clip(gyr, -limit, limit)
    # the same table order with the first run's rate given as -200 deg/s: -300 raw (clipped) is
    # more than 1.2 x 200, the largest raw rate a 20 % scale tolerance allows
    wrong = [-200.0, *ds.ratetable["rates_dps"][1:]]
    with pytest.raises(
        ValueError,
        match=r"run at 6.\d-15.\d s is about x at -(29|30)\d deg/s raw \(clipped at the sensor range\); "
        r"expected x -200 deg/s",
    ):
        segment_ratetable(t, acc, gyr, ds.ratetable["axes"], wrong)
    # with the true rates the clipped runs match
    runs = segment_ratetable(t, acc, gyr, ds.ratetable["axes"], ds.ratetable["rates_dps"])
    assert runs["label"].tolist() == [
        f"{ax}{int(r):+d}" for ax in ds.ratetable["axes"] for r in ds.ratetable["rates_dps"]
    ]
    assert (
        "run(s) x-400, x+400, y-400, y+400, z-400, z+400 clipped"
        in runs.attrs["notes"]["ratetable"]
    )


# --- a consumer part's gyro bias: large, drifting, wandering ----------------------------------


def resting_with_yaws(bias_dps, yaw_dps, drift_dps_per_s=(0.0, 0.0, 0.0), seed=0):
    """z up; 12 rests of 6 s joined by 3-s yaws about z at a constant rate (quiet in both
    sensors: gravity stays on z), the raw rate = bias (+ a linear drift) + rotation + noise.

    Returns t (n,), acc (n, 3), gyr (n, 3) (rad/s) and the rest intervals (s)."""
    rng = np.random.default_rng(seed)
    rests, t_all, w_all, now = [], [], [], 0.0
    for k in range(12):
        for length, rate in ((6.0, 0.0), (3.0, yaw_dps))[: 2 if k < 11 else 1]:
            t = now + np.arange(0, length, 1 / FS)
            t_all.append(t)
            w_all.append(np.outer(np.full(t.size, np.radians(rate)), [0, 0, 1]))
            if rate == 0.0 and length == 6.0:
                rests.append((t[0], t[-1]))
            now = t[-1] + 1 / FS
    t = np.concatenate(t_all)
    drift = np.radians(np.outer(t, drift_dps_per_s))
    gyr = np.concatenate(w_all) + np.radians(bias_dps) + drift + rng.normal(0, 0.0015, (t.size, 3))
    acc = np.array([0, 0, G]) + rng.normal(0, 0.02, (t.size, 3))
    return t, acc, gyr, rests


def test_a_slow_rotation_that_cancels_a_large_bias_is_not_the_rest():
    """An MPU-6050-class bias (-3.7, -7.0, -7.2) deg/s and yaws at +6 deg/s: each yaw is quiet and
    its mean raw rate (-3.7, -7.0, -1.2) is smaller than the bias, so the smallest mean rate is
    a yaw; the rest is the longest chain of equal rates, the 12 true rests."""
    t, acc, gyr, rests = resting_with_yaws((-3.7, -7.0, -7.2), 6.0)
    static = find_static_intervals(t, acc, gyr)
    assert len(static.intervals) == 12
    for (a, b), (t0, t1) in zip(static.intervals, rests):
        assert t0 - 0.6 <= t[a] and t[b - 1] <= t1 + 0.6
    np.testing.assert_allclose(np.degrees(static.rest_rad_s), (-3.7, -7.0, -7.2), atol=0.01)
    assert len(static.rejected) == 11  # the yaws, each named in the notes
    seg = segment_cube(t, acc, gyr, min_positions=1)
    assert "11 quiet interval(s) not at the rest level" in seg.attrs["notes"]["cube"]


def test_a_warm_up_drift_beyond_the_tolerance_keeps_every_rest():
    """A warm-up drift of 0.025 deg/s per s moves the bias by 2.5 deg/s over the recording (more
    than rest_tol_dps): every rest is kept, the rest level follows the drift in time, and the
    note says by how much it moved."""
    t, acc, gyr, _ = resting_with_yaws((5.0, -3.0, 2.0), 60.0, (0.0, 0.025, 0.0))
    static = find_static_intervals(t, acc, gyr)
    assert len(static.intervals) == 12
    true_rest = np.radians(np.array([5.0, -3.0, 2.0]) + np.outer(t, [0, 0.025, 0]))
    inside = (t > static.centres_s[0]) & (t < static.centres_s[-1])
    err = np.degrees(static.rest_at(t) - true_rest)[inside]
    # a linear drift is interpolated exactly; what is left is the noise of a 6-s mean
    # (0.0015 rad/s / sqrt(600) = 0.0035 deg/s), bound at 5 sigma
    assert np.abs(err).max() < 5 * np.degrees(0.0015 / np.sqrt(600))
    assert static.drift_dps() > DetectorSettings().rest_tol_dps
    note = segment_cube(t, acc, gyr, min_positions=1).attrs["notes"]["cube"]
    assert f"rest level (gyro bias) moves by {static.drift_dps():.2f} deg/s" in note


def test_a_phase_clipped_at_the_gyro_range_is_found_by_the_protocol_order(tmp_path):
    """A gyro range of 45 deg/s clips the 50-60 deg/s phases: the raw turns read 1.4-1.9 instead
    of 2, yet the phases are found (x, y, z), with unknown turns and a note; the noise estimate
    ignores the clipped (constant) windows, so the rests are still found."""
    from imucal.sim import ProtocolConfig, make_truth, simulate_session, write_session
    from imucal.sim.effects import make_effect, stream_rng

    truth = make_truth("random", stream_rng(6, "truth"))
    session = simulate_session(
        truth, 7, ProtocolConfig(static_s=20.0), (make_effect("saturation", gyr=2950),)
    )
    _, tables = ingested(write_session(session, tmp_path / "clipped"))
    seg = segment_dataset({"rotation3d": tables["rotation3d"]})
    phases = seg[seg["kind"] == "phase"]
    assert list(phases["label"]) == ["x", "y", "z"]
    assert phases["turns"].isna().all()
    assert "clipped at the gyroscope range" in seg.attrs["notes"]["rotation3d"]


def test_a_cube_turned_by_hand_gets_its_positions_from_the_tremor_adaptive_holds(tmp_path):
    """Holds of 2.5-3.5 s with hand tremor (~1 deg/s rate RMS, ~0.5 deg): the noise-derived
    detector rejects them, the tremor-adaptive holds give the 12 positions, at the true holds
    (each found hold inside its true hold, 0.5 s margin), and the note says which detector."""
    from imucal.sim import ProtocolConfig, make_truth, simulate_session, write_session
    from imucal.sim.effects import make_effect, stream_rng

    truth = make_truth("random", stream_rng(44, "truth"))
    config = ProtocolConfig(cube_position_s=(2.5, 3.5), static_s=20.0)
    folder = write_session(
        simulate_session(truth, 44, config, (make_effect("hand_tremor"),)), tmp_path / "held"
    )
    _, tables = ingested(folder)
    seg = segment_dataset({"cube": tables["cube"]})
    positions = seg[seg["kind"] == "position"]
    assert len(positions) == 12
    true = [
        s for s in json.loads((folder / "truth.json").read_text())["segments"]
        if s["recording"] == "cube"
    ]  # fmt: skip
    for row, s in zip(positions.itertuples(), true, strict=True):
        assert s["start_s"] - 0.5 <= row.start_s and row.end_s <= s["end_s"] + 0.5
    assert "tremor-adaptive detector" in seg.attrs["notes"]["cube"]
    assert seg.attrs["held_by_hand"] == ["cube"]  # the diagnosis leaves these holds out of rest


def _robot_table(rest_s: float) -> tuple[pd.DataFrame, object]:
    """A robot-like session: moves with rests of ``rest_s`` every 20 s (plus the ramps)."""
    s = simulate_orientation_session(3, matrix=np.eye(3), bias=np.array([0.01, 0.0, -0.01]),
                                     mounting=np.eye(3), duration_s=170.0, rest_s=rest_s,
                                     acc_noise_m_s2=0.02)  # fmt: skip
    table = pd.DataFrame({TIME: s.t_module, **dict(zip(ACC, s.acc.T)), **dict(zip(GYR, s.gyr.T))})
    return table, s


@pytest.mark.parametrize("rest_s", [1.0, 1.4])
def test_robot_rests_of_about_one_second_are_found(rest_s):
    table, s = _robot_table(rest_s)
    segments = segment_dataset({"tumble": table}, fallback=True)
    static = segments[segments["kind"] == "static"]
    assert len(static) == len(s.rests_s) and "tumble" not in segments.attrs["notes"]


def test_rests_too_short_are_explained_with_the_settings_that_find_them():
    table, s = _robot_table(0.4)  # 0.5-0.8 s of stillness: below min_static_s = 1 s
    t, acc, gyr = s.t_module, s.acc, s.gyr
    with pytest.raises(ValueError, match="no static interval of at least 1.0 s"):
        find_static_intervals(t, acc, gyr)
    note = short_rest_note("tumble", table, segments_frame([]), DetectorSettings())
    assert note.startswith("tumble: no rest of at least 1 s was found, but 9 still interval")
    assert "segments: in dataset.yaml" in note
    found = re.search(r"segmentation.min_static_s: ([\d.]+) and segmentation.window_s: ([\d.]+)",
                      note)  # fmt: skip
    settings = DetectorSettings(window_s=float(found[2]), min_static_s=float(found[1]))
    assert len(find_static_intervals(t, acc, gyr, settings).intervals) == 9
