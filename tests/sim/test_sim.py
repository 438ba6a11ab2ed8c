"""The protocol simulator: files, determinism, physics against the truth, effects.

Sessions use a 30 s static recording to stay fast; each renders in about a second. Tolerances
come from the simulated white noise (std per axis in ``truth.noise``): a mean of N samples is
allowed 5 standard errors, an integral of N samples 5 random-walk standard deviations.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation

from imucal import errormodel
from imucal.cli import main
from imucal.columns import (
    AXES,
    RAW_COLUMNS,
    REF_ACC,
    REF_COUNTER,
    REF_GYR,
    REF_MAG,
    REF_TIME_FINE,
    SENSOR_COLUMNS,
    SEQ_MODULUS,
)
from imucal.constants import IMU_RECORDINGS
from imucal.io.dataset import read_dataset
from imucal.sim import (
    ProtocolConfig,
    evaluate_motion,
    make_effect,
    make_truth,
    parse_effect,
    simulate,
    simulate_session,
)
from imucal.sim.effects import RecordingContext, stream_rng
from imucal.sim.motion import Motion, Tremor, hold, move, turn
from imucal.sim.protocol import plan_cube
from imucal.sim.session import RATE_HZ, SENSITIVITY
from imucal.sim.truth import PAPER_GYR_BIAS, PAPER_GYR_SCALE, World

SEED = 11
STATIC_S = 30.0
DT = 1 / RATE_HZ


@pytest.fixture(scope="module")
def base(tmp_path_factory) -> Path:
    """Paper preset, no effects."""
    folder = tmp_path_factory.mktemp("sim") / "base"
    simulate(folder, preset="paper", seed=SEED, static_s=STATIC_S)
    return folder


@pytest.fixture(scope="module")
def lossy(tmp_path_factory) -> Path:
    """Same seed as ``base`` with bursty packet loss and a drifting reference clock."""
    folder = tmp_path_factory.mktemp("sim") / "lossy"
    effects = (
        parse_effect("packet_loss:fraction=0.02,model=gilbert,burst_mean=4"),
        parse_effect("time_offset:offset_s=0.27,drift_ppm=40"),
    )
    simulate(folder, preset="paper", seed=SEED, effects=effects, static_s=STATIC_S)
    return folder


def load(folder: Path) -> tuple[dict, dict]:
    truth = json.loads((folder / "truth.json").read_text())
    tables = {rec: pd.read_csv(folder / f"{rec}.csv") for rec in IMU_RECORDINGS}
    return truth, tables


def calibrated(table: pd.DataFrame, truth: dict, sensor: str) -> np.ndarray:
    """Readings of the raw counts calibrated with the true parameters, shape (n, 3)."""
    reading = table[list(SENSOR_COLUMNS[sensor])].to_numpy(float) * SENSITIVITY[sensor]
    return errormodel.apply(truth[sensor]["matrix"], truth[sensor]["bias"], reading)


def calibrated_noise(truth: dict, sensor: str) -> float:
    """Largest per-axis std of the calibrated noise: |row of matrix| * reading noise std."""
    m = np.asarray(truth[sensor]["matrix"])
    quant = SENSITIVITY[sensor] / np.sqrt(12)
    return float(np.linalg.norm(m, axis=1).max() * np.hypot(truth["noise"][sensor], quant))


def segments(truth: dict, recording: str, kind: str | None = None) -> list[dict]:
    return [
        s for s in truth["segments"] if s["recording"] == recording and kind in (None, s["kind"])
    ]


def in_segment(table: pd.DataFrame, seg: dict) -> np.ndarray:
    t = table["t_s"].to_numpy()
    return (t >= seg["start_s"]) & (t < seg["end_s"])


# --- files -----------------------------------------------------------------------------------


def test_same_seed_same_files_other_seed_other_files(base, tmp_path):
    again = tmp_path / "base"
    other = tmp_path / "other"
    simulate(again, preset="paper", seed=SEED, static_s=STATIC_S, name="base")
    simulate(other, preset="paper", seed=SEED + 1, static_s=STATIC_S, name="base")
    names = sorted(p.name for p in base.iterdir())
    assert names == sorted(p.name for p in again.iterdir())
    for name in names:
        assert (base / name).read_bytes() == (again / name).read_bytes(), name
    for name in ("rotation3d.csv", "cube.csv", "static.csv", "mtx_rotation3d.txt"):
        assert (base / name).read_bytes() != (other / name).read_bytes(), name


def test_dataset_yaml_validates(base):
    ds = read_dataset(base)
    assert ds.name == "base"
    assert ds.sensitivity == SENSITIVITY
    assert sorted(ds.recordings) == sorted(
        ("rotation3d", "cube", "ratetable", "static", "reference")
    )
    assert all(p.is_file() for p in ds.recordings.values())
    assert ds.ratetable == {"axes": ["x", "y", "z"], "rates_dps": list(range(-400, 401, 100))}
    # the folder says it is simulated and where its truth is (the report's banner)
    assert ds.simulated == {
        "by": f"imucal.sim, preset paper, seed {SEED}, effects: none",
        "truth": base / "truth.json",
    }


def test_a_simulated_declaration_names_an_existing_truth(base, tmp_path):
    folder = tmp_path / "copy"
    folder.mkdir()
    for path in base.iterdir():
        (folder / path.name).symlink_to(path)
    (folder / "dataset.yaml").unlink()
    text = (base / "dataset.yaml").read_text()
    (folder / "dataset.yaml").write_text(text.replace("truth: truth.json", "truth: truth2.json"))
    with pytest.raises(FileNotFoundError, match="key 'simulated/truth': 'truth2.json' is not a"):
        read_dataset(folder)
    # a recorded session declares nothing: no banner
    (folder / "dataset.yaml").write_text(
        "\n".join(
            line
            for line in text.splitlines()
            if not line.startswith(("simulated", "  by", "  truth"))
        )
    )
    assert read_dataset(folder).simulated is None


def test_csv_header_time_and_magnetometer_cells(base):
    _, tables = load(base)
    for rec in IMU_RECORDINGS:
        lines = (base / f"{rec}.csv").read_text().splitlines()
        assert lines[0] == ",".join(RAW_COLUMNS)
        # 10 Hz magnetometer: a sample on every 10th packet, three empty cells elsewhere
        has_mag = np.array([not line.endswith(",,,") for line in lines[1:]])
        k = np.arange(len(has_mag))
        np.testing.assert_array_equal(has_mag, k % 10 == 0)
        t = tables[rec]["t_s"].to_numpy()
        np.testing.assert_allclose(t, k * DT, atol=5e-5)  # 4 decimals, no jitter
        assert all(len(line.split(",")[0].split(".")[1]) == 4 for line in lines[1:50])


def test_seq_is_16_bit_and_wraps_in_the_longest_recording(base):
    _, tables = load(base)
    longest = max(IMU_RECORDINGS, key=lambda r: len(tables[r]))
    for rec in IMU_RECORDINGS:
        seq = tables[rec]["seq"].to_numpy()
        assert seq.min() >= 0 and seq.max() < SEQ_MODULUS
        np.testing.assert_array_equal(np.diff(seq) % SEQ_MODULUS, 1)
    assert np.any(np.diff(tables[longest]["seq"].to_numpy()) < 0)


def test_truth_json_matrices_decompose_to_its_parameters(base):
    truth, _ = load(base)
    for s in ("acc", "gyr", "mag"):
        d = errormodel.decompose(truth[s]["matrix"])
        np.testing.assert_allclose(d.scale, truth[s]["scale"], atol=1e-12)
        np.testing.assert_allclose(d.xi_rad, truth[s]["xi"], atol=1e-12)
        np.testing.assert_allclose(d.alpha_rad, truth[s]["alpha"], atol=1e-12)
    # paper preset: Zhang et al. (2014) Tables I and II, "with tools"
    np.testing.assert_allclose(truth["gyr"]["bias"], PAPER_GYR_BIAS)
    np.testing.assert_allclose(truth["gyr"]["scale"], PAPER_GYR_SCALE)
    assert truth["seed"] == SEED and truth["effects"] == {}
    assert {"gravity_m_s2", "field", "noise", "reference", "segments"} <= set(truth)


def test_segments_have_the_architecture_labels(base):
    truth, _ = load(base)
    labels = {rec: [s["label"] for s in segments(truth, rec, kind)] for rec, kind in (
        ("rotation3d", "phase"), ("cube", "position"), ("ratetable", "run"), ("static", None))}  # fmt: skip
    assert labels["rotation3d"] == ["x", "y", "z"]
    assert labels["cube"] == [f"p{i:02d}" for i in range(1, 13)]
    assert labels["ratetable"] == [f"{a}{r:+d}" for a in AXES for r in range(-400, 401, 100)]
    assert labels["static"] == ["s01"]
    for rec in IMU_RECORDINGS:
        seg = segments(truth, rec)
        starts = [s["start_s"] for s in seg]
        assert starts == sorted(starts) and all(s["end_s"] > s["start_s"] for s in seg)


# --- physics against the truth ----------------------------------------------------------------


def test_static_norms_are_gravity_and_unit_field(base):
    truth, tables = load(base)
    g = truth["gravity_m_s2"]
    sigma_a, sigma_m = calibrated_noise(truth, "acc"), calibrated_noise(truth, "mag")
    static = [("static", s) for s in segments(truth, "static")]
    static += [("cube", s) for s in segments(truth, "cube", "position")]
    for rec, seg in static:
        rows = tables[rec][in_segment(tables[rec], seg)]
        a = np.linalg.norm(calibrated(rows, truth, "acc"), axis=1)
        m = np.linalg.norm(calibrated(rows.dropna(), truth, "mag"), axis=1)
        # the norm's noise is the noise along the vector: std sigma per sample
        assert abs(a.mean() - g) < 5 * sigma_a / np.sqrt(a.size), (rec, seg["label"])
        assert abs(m.mean() - 1) < 5 * sigma_m / np.sqrt(m.size), (rec, seg["label"])
        assert 0.8 * sigma_a < a.std() < 1.2 * sigma_a
        # and truly static: the gyroscope sees noise only
        w = calibrated(rows, truth, "gyr")
        assert np.all(np.abs(w.mean(axis=0)) < 5 * calibrated_noise(truth, "gyr") / np.sqrt(len(w)))


def test_cube_positions_point_gravity_along_the_protocol_directions(base):
    truth, tables = load(base)
    ups = [s for s in segments(truth, "cube", "position")]
    expected = np.array(
        [(0, 0, 1), (0, 0, -1), (1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0),
         (0, 1, 1), (0, 1, -1), (1, 0, 1), (1, 0, -1), (1, 1, 0), (1, -1, 0)], float
    )  # fmt: skip
    expected /= np.linalg.norm(expected, axis=1, keepdims=True)
    for seg, up in zip(ups, expected):
        a = calibrated(tables["cube"][in_segment(tables["cube"], seg)], truth, "acc").mean(axis=0)
        np.testing.assert_allclose(a / np.linalg.norm(a), up, atol=1e-3)


def test_rate_table_plateaus_give_the_nominal_rate(base):
    truth, tables = load(base)
    sigma = calibrated_noise(truth, "gyr")
    for seg in segments(truth, "ratetable", "run"):
        rows = tables["ratetable"][in_segment(tables["ratetable"], seg)]
        w = calibrated(rows, truth, "gyr")
        nominal = np.radians(seg["rate_dps"]) * np.eye(3)[AXES.index(seg["axis"])]
        tol = 5 * sigma / np.sqrt(len(w))
        np.testing.assert_allclose(w.mean(axis=0), nominal, atol=tol, err_msg=seg["label"])
        # constant: the per-sample spread is the noise, no leftover of the ramps
        assert w.std(axis=0).max() < 1.2 * sigma, seg["label"]
    assert sum(truth["clipped_counts"]["ratetable"].values()) == 0


def test_rotation3d_phases_integrate_to_the_nominal_angle(base):
    truth, tables = load(base)
    sigma = calibrated_noise(truth, "gyr")
    table = tables["rotation3d"]
    for seg in segments(truth, "rotation3d"):
        if seg["kind"] not in ("phase", "transition"):
            continue
        mask = in_segment(table, seg)
        angle = calibrated(table[mask], truth, "gyr").sum(axis=0) * DT
        nominal = 2 * np.pi * seg["turns"] * np.eye(3)[AXES.index(seg["axis"])]
        # random walk of the noise over the phase, plus the rectangle rule (exact to ~1e-6 here)
        tol = 5 * sigma * DT * np.sqrt(mask.sum())
        np.testing.assert_allclose(angle, nominal, atol=tol, err_msg=seg["label"])
    assert [s["turns"] for s in segments(truth, "rotation3d", "phase")] == [2.0, -2.0, 2.0]


# --- effects ------------------------------------------------------------------------------------


def test_packet_loss_drops_rows_at_the_configured_fraction_and_changes_nothing_else(base, lossy):
    truth, full = load(base)
    truth_lossy, tables = load(lossy)
    assert truth_lossy["effects"]["packet_loss"]["fraction"] == 0.02
    lost, total, bursts = 0, 0, 0
    for rec in IMU_RECORDINGS:
        a, b = full[rec], tables[rec]
        step = np.diff(b["seq"].to_numpy()) % SEQ_MODULUS
        assert step.min() >= 1
        bursts += np.count_nonzero(step > 1)
        lost += len(a) - len(b)
        total += len(a)
        # the kept rows are the loss-free rows, byte for byte
        kept = a.set_index("t_s").loc[b["t_s"]].reset_index()
        pd.testing.assert_frame_equal(kept, b)
    # Gilbert channel: variance of the loss count is inflated by (1 + rho) / (1 - rho) ~ 2 b - 1
    # with b = 4 the mean burst length; allow 5 standard deviations
    f, b = 0.02, 4
    sd = np.sqrt(total * f * (1 - f) * (2 * b - 1)) / total
    assert abs(lost / total - f) < 5 * sd
    assert 2 < lost / bursts < 8  # mean burst length near 4 (bursts may merge or be split)
    assert truth_lossy["segments"] == truth["segments"]


def test_reference_parses_and_matches_mounting_and_clock(lossy):
    truth, tables = load(lossy)
    path = lossy / "mtx_rotation3d.txt"
    head = [line for line in path.read_text().splitlines()[:6]]
    assert all(line.startswith("// ") for line in head) and "// Update Rate: 100.0Hz" in head
    ref = pd.read_csv(path, sep="\t", comment="/")
    assert list(ref.columns) == [REF_COUNTER, REF_TIME_FINE, *REF_ACC, *REF_GYR, *REF_MAG]
    np.testing.assert_array_equal(np.diff(ref[REF_TIME_FINE]), 100)  # 10 kHz ticks at 100 Hz
    np.testing.assert_allclose(np.linalg.norm(ref[list(REF_MAG)], axis=1).mean(), 1, atol=1e-3)
    info = truth["reference"]
    assert info["time_offset_s"] == 0.27 and info["clock_drift_ppm"] == 40
    tau = (ref[REF_TIME_FINE] - ref[REF_TIME_FINE].iloc[0]).to_numpy() / 1e4
    w_ref = ref[list(REF_GYR)].to_numpy()
    module = tables["rotation3d"]
    w_mod = calibrated(module, truth, "gyr")

    def module_rate_at(offset_s: float) -> np.ndarray:
        t = tau / (1 + info["clock_drift_ppm"] * 1e-6) - offset_s
        return np.column_stack([np.interp(t, module["t_s"], w_mod[:, j]) for j in range(3)])

    moving = np.linalg.norm(w_ref, axis=1) > 0.3
    # mounting: v_B = R v_ref. Noise bound ~ sigma / |w| / sqrt(N) ~ 3e-5 rad; allow 5e-4 rad
    rot, _ = Rotation.align_vectors(module_rate_at(info["time_offset_s"])[moving], w_ref[moving])
    err = rot * Rotation.from_rotvec(info["mounting_rotvec_rad"]).inv()
    assert err.magnitude() < 5e-4
    # clock: the documented sign of the offset is the one that lines the two up best
    candidates = info["time_offset_s"] + np.arange(-0.05, 0.0501, 0.005)
    rms = [
        np.sqrt(np.mean((rot.apply(w_ref[moving]) - module_rate_at(c)[moving]) ** 2))
        for c in candidates
    ]
    assert abs(candidates[int(np.argmin(rms))] - info["time_offset_s"]) < 1e-9
    assert 1.0 < np.degrees(np.linalg.norm(info["mounting_rotvec_rad"])) < 3.0


def _context(recording: str = "static", session_start_s: float = 0.0) -> RecordingContext:
    return RecordingContext(recording, RATE_HZ, session_start_s, SENSITIVITY, SEED)


def _render_parts(seed: int = SEED):
    """True signals of a short motion: static, then a ramped turn about y at 200 deg/s."""
    r0 = Rotation.from_euler("z", 0.4)
    spin = turn(2.0, 6.0, r0, [0, 1, 0], np.radians(200) * 5.0, ramp_s=1.0)
    from imucal.sim.motion import hold
    from imucal.sim.sensors import true_signals

    motion = Motion((hold(0.0, 2.0, r0), spin))
    state = evaluate_motion(motion, np.arange(0, 8.0, DT))
    return state, true_signals(state, World())


def test_timing_jitter_delays_stamps_and_keeps_them_non_decreasing():
    from imucal.sim.packets import build_packet_log

    n = 20000
    counts = {s: np.zeros((n, 3), dtype=int) for s in ("acc", "gyr", "mag")}
    log = build_packet_log(counts, 65000, RATE_HZ)
    jittered = make_effect("timing_jitter", std_s=0.004).on_packets(log, _context())
    delay = jittered.t_s - log.t_s
    assert np.all(np.diff(jittered.t_s) >= 0) and np.all(delay >= 0)
    # exponential delays, then a running maximum: the mean is std_s plus a little
    assert 0.004 < delay.mean() < 0.006
    np.testing.assert_array_equal(jittered.seq, log.seq)


def test_earth_rotation_adds_the_earth_rate_in_b():
    state, true = _render_parts()
    out = make_effect("earth_rotation", latitude_deg=48.0).on_true_signals(true, state, _context())
    added = out.gyr - true.gyr
    np.testing.assert_allclose(np.linalg.norm(added, axis=1), 7.2921150e-5, rtol=1e-12)
    # at rest with z up the vertical component is Omega sin(latitude)
    np.testing.assert_allclose(added[0, 2], 7.2921150e-5 * np.sin(np.radians(48.0)), rtol=1e-9)
    np.testing.assert_array_equal(out.acc, true.acc)


def test_lever_arm_adds_centripetal_acceleration_on_the_plateau():
    state, true = _render_parts()
    out = make_effect("lever_arm", x_m=0.05, y_m=0.0, z_m=0.02).on_true_signals(
        true, state, _context()
    )
    plateau = (state.t_s > 3.05) & (state.t_s < 6.95)
    w = np.radians(200)
    # rotation about y: the x and z offsets are radial, centripetal -w^2 r
    np.testing.assert_allclose(
        (out.acc - true.acc)[plateau],
        np.tile([-(w**2) * 0.05, 0, -(w**2) * 0.02], (plateau.sum(), 1)),
        atol=1e-9,
    )


def test_g_sensitivity_adds_k_times_specific_force_to_the_gyro():
    """``G`` acts in frame B: the raw gyro reading moves by ``K^-1 G a_B``; one number is a
    diagonal ``G``, a spec string gives the matrix row by row."""
    state, true = _render_parts()
    cal = make_truth("paper", stream_rng(1, "truth")).calibration
    ctx = dataclasses.replace(_context(), calibration=cal)
    g = np.array([[1e-3, 2e-4, 0.0], [0.0, 0.0, -3e-4], [5e-5, 0.0, -2e-3]])
    effect = parse_effect("g_sensitivity:matrix=" + ";".join(map(str, g.ravel())))
    np.testing.assert_array_equal(effect.matrix, g)
    out = effect.on_readings(true, true, state, ctx)
    want = true.acc @ np.linalg.solve(cal.gyr.matrix, g).T
    np.testing.assert_allclose(out.gyr - true.gyr, want, atol=1e-15)
    assert make_effect("g_sensitivity", matrix=2e-4).matrix == tuple(
        tuple(2e-4 * (i == j) for j in range(3)) for i in range(3)
    )
    with pytest.raises(ValueError, match="parameter matrix has 4 values, expected 1 or 9"):
        make_effect("g_sensitivity", matrix=[1, 2, 3, 4])


def test_saturation_and_temperature_drift_in_a_written_session(tmp_path):
    effects = (
        parse_effect("saturation:gyr=20000"),
        parse_effect("temperature_drift:rise_c=10,tau_s=300,gyr_per_k=0.001,acc_per_k=0"),
    )
    folder = tmp_path / "hot"
    simulate(folder, preset="paper", seed=SEED, effects=effects, static_s=STATIC_S)
    truth, tables = load(folder)
    assert read_dataset(folder).range_counts["gyr"] == 20000
    gyr = tables["ratetable"][list(SENSOR_COLUMNS["gyr"])].to_numpy()
    assert np.abs(gyr).max() == 20000  # 400 deg/s needs ~23000 counts with the paper scale
    temps = [tables[r]["temp_c"].to_numpy() for r in IMU_RECORDINGS]
    assert all(np.all(np.diff(t) >= 0) for t in temps) and temps[-1][-1] > temps[0][0] + 5
    # the static recording's gyro bias moved by gyr_per_k * (T - start): check the mean change
    static = tables["static"]
    w = calibrated(static, truth, "gyr")
    m = np.asarray(truth["gyr"]["matrix"])
    expected = m @ (0.001 * np.ones(3)) * (static["temp_c"].mean() - 22.0)
    sigma = calibrated_noise(truth, "gyr")
    np.testing.assert_allclose(w.mean(axis=0), expected, atol=5 * sigma / np.sqrt(len(w)) + 1e-5)


def test_random_preset_is_seeded_and_fits_int16_at_400_dps():
    a = make_truth("random", stream_rng(1, "truth"))
    b = make_truth("random", stream_rng(1, "truth"))
    c = make_truth("random", stream_rng(2, "truth"))
    np.testing.assert_array_equal(a.calibration.gyr.matrix, b.calibration.gyr.matrix)
    assert not np.allclose(a.calibration.gyr.matrix, c.calibration.gyr.matrix)
    for seed in range(200):
        gyr = make_truth("random", stream_rng(seed, "truth")).calibration.gyr
        rates = np.radians(400) * np.vstack([np.eye(3), -np.eye(3)])
        reading = errormodel.invert(gyr.matrix, gyr.bias, rates)
        assert np.abs(reading).max() / SENSITIVITY["gyr"] < 32767 - 100  # margin: 20 noise std


def test_mems_preset_has_consumer_turn_on_biases_and_fits_int16_at_400_dps():
    truths = [make_truth("mems", stream_rng(seed, "truth")) for seed in range(300)]
    gyr_bias = np.array([t.calibration.gyr.bias for t in truths])
    acc_bias = np.array([t.calibration.acc.bias for t in truths])
    assert np.abs(gyr_bias).max() <= np.radians(20.0) and np.abs(gyr_bias).max() > 0.3
    assert np.abs(acc_bias).max() <= 0.6 and np.abs(acc_bias).max() > 0.55
    assert np.abs(acc_bias).min() >= 0.05
    scales = np.array([t.calibration.gyr.decomposition.scale for t in truths])
    assert 0.95 <= scales.min() and scales.max() <= 1.2  # as in the random preset
    assert all(t.preset == "mems" for t in truths)
    limit = 32767 - 100  # margin: 20 noise std
    for t in truths:
        gyr = t.calibration.gyr
        # worst reading of a 400 deg/s rate along any direction: |row of inv(matrix)| * rate
        worst = np.linalg.norm(np.linalg.inv(gyr.matrix), axis=1) * np.radians(400) + np.abs(
            gyr.bias
        )
        assert worst.max() / SENSITIVITY["gyr"] < limit
    # the other presets keep their ranges
    random = np.array([make_truth("random", stream_rng(s, "truth")).calibration.gyr.bias
                       for s in range(300)])  # fmt: skip
    assert np.abs(random).max() <= 0.2


def test_slow_handling_motions_take_their_configured_time():
    config = ProtocolConfig(cube_move_s=(8.0, 12.0), cube_position_s=(2.5, 3.5))
    plan = plan_cube(config, stream_rng(3, "protocol"))
    moves = [p for p in plan.motion.pieces if p.profile == "smooth"]
    holds = [p for p in plan.motion.pieces if p.profile == "hold"]
    assert len(moves) == 11 and len(holds) == 12
    assert all(8.0 <= p.duration_s <= 12.0 for p in moves)
    assert all(2.5 <= p.duration_s <= 3.5 for p in holds)
    t = np.arange(0.0, plan.motion.duration_s, DT)
    state = evaluate_motion(plan.motion, t)
    fast = evaluate_motion(plan_cube(ProtocolConfig(), stream_rng(3, "protocol")).motion, t)
    # the same turns over about 3.5 times the time: the peak rate drops accordingly
    assert (
        np.linalg.norm(state.omega_b, axis=1).max()
        < 0.5 * np.linalg.norm(fast.omega_b, axis=1).max()
    )


def assert_rates_are_derivatives(state, t, atol_dot):
    """The body rate is the derivative of the orientation and the angular acceleration that of
    the rate (finite differences, O(h^2) of the midpoint rule); ``t`` (n,) evenly spaced, s."""
    h = t[1] - t[0]
    finite = (state.rotation[:-1].inv() * state.rotation[1:]).as_rotvec() / h
    midpoint = (state.omega_b[:-1] + state.omega_b[1:]) / 2
    np.testing.assert_allclose(finite, midpoint, atol=1e-7)
    np.testing.assert_allclose(
        np.diff(state.omega_b, axis=0) / h,
        (state.omega_dot_b[:-1] + state.omega_dot_b[1:]) / 2,
        atol=atol_dot,
    )


def test_tremor_rates_are_the_derivative_of_the_orientation():
    rng = np.random.default_rng(0)
    tremor = Tremor(
        np.radians(np.array([[0.3, 0.3, 0.01, 0.01]] * 3)),
        np.hstack([rng.uniform(0.1, 0.8, (3, 2)), rng.uniform(4.0, 12.0, (3, 2))]),
        rng.uniform(0.0, 2 * np.pi, (3, 4)),
        0.5,
    )
    r0 = Rotation.from_rotvec([0.2, -0.4, 1.0])
    target = Rotation.from_rotvec([1.0, 0.5, -0.3])
    for base in (hold(0.0, 3.0, r0), move(0.0, 3.0, r0, target, [0, 0.6, 0.8], 0.05, 1.5)):
        piece = dataclasses.replace(base, tremor=tremor)
        t = np.linspace(0.0, 3.0, 30001)
        state = evaluate_motion(Motion((piece,)), t)
        assert_rates_are_derivatives(state, t, atol_dot=1e-5)
        # starts and ends at rest on the piece's own orientations (the envelope)
        assert (state.rotation[0].inv() * piece.start).magnitude() < 1e-12
        assert (state.rotation[-1].inv() * piece.end).magnitude() < 1e-12
        np.testing.assert_allclose(state.omega_b[[0, -1]], evaluate_motion(
            Motion((base,)), t[[0, -1]]).omega_b, atol=1e-12)  # fmt: skip
    with pytest.raises(ValueError, match="share one shape"):
        Tremor(np.zeros((3, 2)), np.zeros((3, 3)), np.zeros((3, 2)), 0.5)


@pytest.mark.parametrize(
    ("config", "gyr_counts"),
    [
        (ProtocolConfig(static_s=STATIC_S), 1965),  # a 30 deg/s range below the phase rates
        (ProtocolConfig(static_s=STATIC_S, phase_rate_dps=(300.0, 300.0, 300.0)), 16375),
    ],
)
def test_saturation_clips_inside_the_rotation3d_phases(config, gyr_counts):
    truth = make_truth("paper", stream_rng(SEED, "truth"))
    saturation = make_effect("saturation", gyr=gyr_counts)
    on = simulate_session(truth, SEED, config, (saturation,))
    off = simulate_session(truth, SEED, config)
    counts = on.logs["rotation3d"].counts["gyr"]
    t = on.logs["rotation3d"].sample / RATE_HZ
    for seg in on.plans["rotation3d"].segments:
        if seg.kind != "phase":
            continue
        # the plateau: ramps of phase_ramp_s at both ends
        m = (t >= seg.start_s + config.phase_ramp_s) & (t < seg.end_s - config.phase_ramp_s)
        j = AXES.index(seg.axis)
        assert np.all(np.abs(counts[m, j]) == gyr_counts), seg.label
        assert np.all(np.abs(off.logs["rotation3d"].counts["gyr"][m, j]) > gyr_counts)
    assert np.abs(counts).max() == gyr_counts
    np.testing.assert_array_equal(on.logs["cube"].counts["acc"], off.logs["cube"].counts["acc"])


def test_motion_rates_are_the_derivative_of_the_orientation():
    r0 = Rotation.from_rotvec([0.2, -0.4, 1.0])
    piece = move(0.0, 3.0, r0, Rotation.from_rotvec([1.0, 0.5, -0.3]), [0, 0.6, 0.8], 0.05, 1.5)
    t = np.linspace(0.0, 3.0, 30001)
    state = evaluate_motion(Motion((piece,)), t)
    assert_rates_are_derivatives(state, t, atol_dot=1e-6)


def test_bad_effect_specs_are_rejected_with_the_offending_value():
    with pytest.raises(ValueError, match="unknown effect 'packet_los'"):
        parse_effect("packet_los:fraction=0.1")
    with pytest.raises(ValueError, match=r"no parameters \['rate'\]"):
        parse_effect("packet_loss:rate=0.1")
    with pytest.raises(ValueError, match="fraction=.abc. is not a valid float"):
        parse_effect("packet_loss:fraction=abc")
    with pytest.raises(ValueError, match="fraction must be in"):
        parse_effect("packet_loss:fraction=1.5")
    with pytest.raises(ValueError, match="each effect may be given once"):
        simulate_session(make_truth("paper", stream_rng(0, "t")), 0, ProtocolConfig(static_s=1.0),
                         (make_effect("time_offset"), make_effect("time_offset")))  # fmt: skip


def test_cli_simulate_writes_a_dataset(tmp_path, capsys):
    out = tmp_path / "cli_demo"
    status = main(["simulate", str(out), "--preset", "demo", "--seed", "3", "--static-s", "20",
                   "--effect", "timing_jitter:std_s=0.002"])  # fmt: skip
    assert status == 0 and "cli_demo" in capsys.readouterr().out
    truth = json.loads((out / "truth.json").read_text())
    assert set(truth["effects"]) == {"packet_loss", "time_offset", "timing_jitter"}
    assert truth["preset"] == "demo" and 0.1 <= truth["reference"]["time_offset_s"] <= 0.5
    assert read_dataset(out).name == "cli_demo"
    with pytest.raises(SystemExit):
        main(["simulate", str(out), "--effect", "nonsense"])
