"""The canonical simulator effects: each one's signature appears where expected, not elsewhere.

Every test renders the same short session (paper truth, seed ``SEED``, 60 s static recording)
with and without the effect. The white noise, the protocol and every other random stream are the
same in both (one stream per purpose), so for effects that leave the rows alone the difference
``on - off`` of the readings is the effect plus a rounding difference of at most one count per
sample; tolerances below are derived from that, or from the white noise (``truth.noise``) where
an effect changes which noise sample is reported. A mean of N samples gets 5 standard errors.
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from imucal import errormodel
from imucal.columns import AXES, SENSORS
from imucal.gap.library import scope_library
from imucal.sim import ProtocolConfig, evaluate_motion, make_truth, simulate_session, write_session
from imucal.sim.effects import (
    CANONICAL,
    EFFECTS,
    MOTION_EFFECTS,
    PROTOCOL_EFFECTS,
    REALISTIC,
    REFERENCE_EFFECTS,
    make_effect,
    parse_effect,
    platform_yaw,
    stream_rng,
)
from imucal.sim.effects.kinematic import EARTH_RATE_RAD_S
from imucal.sim.sensors import INT16_MAX
from imucal.sim.session import RATE_HZ, SESSION_GAP_S
from imucal.validation import packet_times

SEED = 7
CONFIG = ProtocolConfig(static_s=60.0)


@pytest.fixture(scope="module")
def truth():
    return make_truth("paper", stream_rng(SEED, "truth"))


@pytest.fixture(scope="module")
def base(truth):
    return simulate_session(truth, SEED, CONFIG)


def render(truth, *effects):
    return simulate_session(truth, SEED, CONFIG, tuple(effects))


def reading(session, rec: str, sensor: str) -> np.ndarray:
    """Readings in SI (sensor frame), shape (n, 3)."""
    return session.logs[rec].counts[sensor] * session.sensitivity[sensor]


def calibrated(session, rec: str, sensor: str) -> np.ndarray:
    """Readings calibrated with the session's true calibration (B, SI), shape (n, 3)."""
    cal = session.truth.calibration.sensor(sensor)
    return errormodel.apply(cal.matrix, cal.bias, reading(session, rec, sensor))


def module_time(session, rec: str) -> np.ndarray:
    return session.logs[rec].sample / RATE_HZ


def mask(session, rec: str, seg) -> np.ndarray:
    t = module_time(session, rec)
    return (t >= seg.start_s) & (t < seg.end_s)


def segs(session, rec: str, kind: str):
    return [s for s in session.plans[rec].segments if s.kind == kind]


def same_counts(a, b, recs=("rotation3d", "cube", "ratetable", "static"), sensors=SENSORS):
    return all(
        np.array_equal(a.logs[r].counts[s], b.logs[r].counts[s]) for r in recs for s in sensors
    )


def count_tol(session, sensor: str, n: int) -> float:
    """5 standard errors of a mean of n rounding differences (each within one count)."""
    return 5 * session.sensitivity[sensor] / math.sqrt(n) + 1e-12


# --- the table ------------------------------------------------------------------------------


def test_every_effect_is_registered_with_realistic_defaults_and_a_magnitude():
    every = CANONICAL + PROTOCOL_EFFECTS + REFERENCE_EFFECTS + MOTION_EFFECTS
    # the canonical effects are those the full protocol's diagnosis estimates (their specs)
    assert set(CANONICAL) == set(scope_library("protocol"))
    assert sorted(every) == sorted(EFFECTS) and len(set(every)) == len(every)
    for name in every:
        effect = make_effect(name)
        assert REALISTIC[name] == effect.params() == EFFECTS[name].realistic()
        m = effect.magnitude()
        assert m.value > 0 and math.isfinite(m.value) and m.unit and m.meaning, name
        np.testing.assert_allclose(effect.scaled(0.5).magnitude().value, m.value / 2, rtol=1e-3)
        # parameters survive truth.json: the scorer rebuilds the effect and its magnitude
        again = make_effect(name, **json.loads(json.dumps(effect.params())))
        assert again == effect
    with pytest.raises(ValueError, match="'lever_arm': scale factor must be > 0"):
        make_effect("lever_arm").scaled(0.0)


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ("bias_instability:gyr_tau_s=0", "bias_instability gyr_tau_s must be > 0 s, got 0.0"),
        ("bias_instability:acc_rw=-1", "bias_instability acc_rw must be >= 0"),
        ("mag_latency:rate_hz=0", "mag_latency rate_hz must be > 0 Hz"),
        ("mag_latency:delay_s=-0.1", "mag_latency delay_s must be >= 0 s"),
        ("placement_error:cube_sigma_deg=-1", "placement_error cube_sigma_deg must be >= 0"),
        ("large_misalignment:mag_deg=-2", "large_misalignment mag_deg must be >= 0"),
        ("scale_nonlinearity:gyr_k5=1", r"'scale_nonlinearity' has no parameters \['gyr_k5'\]"),
    ],
)
def test_bad_parameters_name_the_effect_and_the_parameter(spec, message):
    with pytest.raises(ValueError, match=message):
        parse_effect(spec)


def test_truth_json_records_params_and_realised_draws(truth, tmp_path):
    effects = (make_effect("placement_error"), make_effect("bias_instability"))
    folder = write_session(render(truth, *effects), tmp_path / "s")
    data = json.loads((folder / "truth.json").read_text())
    assert data["effects"] == {e.name: e.params() for e in effects}
    realised = data["effects_realised"]
    assert sorted(realised["placement_error"]["cube"]) == [f"p{i:02d}" for i in range(1, 13)]
    assert sorted(realised["placement_error"]["ratetable"]) == list(AXES)
    assert sorted(realised["bias_instability"]) == ["cube", "ratetable", "rotation3d", "static"]
    # no draws, no key: the files of sessions without such effects are unchanged
    assert "effects_realised" not in render(truth, make_effect("lever_arm")).truth_dict()


# --- sensor effects ----------------------------------------------------------------------------


def test_temperature_drift_follows_the_temperature_column(truth, base):
    effect = make_effect("temperature_drift", rise_c=10.0, tau_s=300.0)
    on = render(truth, effect)
    temps = [on.logs[r].extra["temp_c"] for r in on.logs]
    assert all(np.all(np.diff(t) >= 0) for t in temps) and temps[-1][-1] > temps[0][0] + 5
    # each axis drifts by its own coefficient, of either sign (a real part's shape)
    k_gyr, s_gyr = effect.coefficients("gyr")
    assert np.any(k_gyr < 0) and np.any(k_gyr > 0) and np.any(s_gyr < 0)
    for rec in on.logs:
        dT = on.logs[rec].extra["temp_c"] - effect.start_c
        # static: the gyro reads ~0, so only the bias drift gyr_per_k * dT shows
        d = reading(on, rec, "gyr") - reading(base, rec, "gyr")
        for seg in segs(on, rec, "static") + segs(on, rec, "position"):
            m = mask(on, rec, seg)
            expected = k_gyr * dT[m].mean()  # temp_c is rounded to 0.01 K
            tol = count_tol(on, "gyr", m.sum()) + np.abs(k_gyr) * 0.005
            assert np.all(np.abs(d[m].mean(axis=0) - expected) <= tol), (seg.label, expected)
    # rate table: the scale drift multiplies the input, u (1 + gyr_scale_per_k dT)
    cal = truth.calibration.gyr
    d = reading(on, "ratetable", "gyr") - reading(base, "ratetable", "gyr")
    dT = on.logs["ratetable"].extra["temp_c"] - effect.start_c
    for seg in segs(on, "ratetable", "run"):
        m = mask(on, "ratetable", seg)
        u = errormodel.invert(
            cal.matrix, np.zeros(3), np.radians(seg.rate_dps) * np.eye(3)[AXES.index(seg.axis)]
        )
        expected = (k_gyr + s_gyr * u) * dT[m].mean()
        tol = count_tol(on, "gyr", m.sum()) + (np.abs(k_gyr) + 1e-4 * 8) * 0.005
        assert np.all(np.abs(d[m].mean(axis=0) - expected) <= tol), (seg.label, expected)
    assert same_counts(on, base, sensors=("mag",))  # mag coefficients are 0 by default


def test_bias_instability_is_one_realisation_on_the_session_clock(truth, base):
    # random walk only, exaggerated (x500) so that 10 s increments are ~12 counts
    q = 1e-3
    effect = make_effect("bias_instability", gyr_rw=q, gyr_gm=0.0, acc_rw=0.0, acc_gm=0.0)
    on = render(truth, effect)
    assert same_counts(on, base, sensors=("acc", "mag"))  # nowhere else
    starts, t = {}, 0.0
    for rec, plan in on.plans.items():
        starts[rec] = t
        t += plan.motion.duration_s + SESSION_GAP_S
    increments = []
    for rec in on.logs:
        d = reading(on, rec, "gyr") - reading(base, rec, "gyr")
        t_session = starts[rec] + module_time(on, rec)
        # the difference is the process at the session time of each sample
        expected = effect.bias(t_session, RATE_HZ, SEED)["gyr"]
        assert np.abs(d - expected).max() <= on.sensitivity["gyr"] * (1 + 1e-9)
        np.testing.assert_allclose(
            on.realised["bias_instability"][rec]["mean_bias"]["gyr"], expected.mean(axis=0)
        )
        increments.append(np.diff(expected[::1000], axis=0))
    # random walk: increments over L = 10 s have variance q^2 L; ~170 of them -> 5 sd ~ 55 %
    inc = np.concatenate(increments)
    ratio = inc.var() / (q**2 * 10.0)
    assert 0.45 < ratio < 1.55, ratio
    # the process through a gap: drawing a shorter span gives the same values (one realisation)
    short = effect.bias(np.linspace(0, 100, 50), RATE_HZ, SEED)["gyr"]
    long = effect.bias(np.linspace(0, 100, 50).tolist() + [900.0], RATE_HZ, SEED)["gyr"][:-1]
    np.testing.assert_array_equal(short, long)


def test_bias_instability_gauss_markov_has_its_std_and_correlation_time():
    effect = make_effect(
        "bias_instability", acc_rw=0.0, gyr_rw=0.0, acc_gm=0.0, gyr_gm=0.01, gyr_tau_s=5.0
    )
    t = np.arange(0.0, 5000.0, 0.5)
    b = effect.bias(t, RATE_HZ, SEED)["gyr"]
    # 5000 s / 5 s = 1000 correlation times per axis, 3 axes: the std to ~2 %, allow 10 %
    np.testing.assert_allclose(b.std(axis=0), 0.01, rtol=0.1)
    lag = 10  # 5 s
    rho = np.mean([np.corrcoef(b[:-lag, j], b[lag:, j])[0, 1] for j in range(3)])
    assert abs(rho - np.exp(-1.0)) < 0.08


def test_g_sensitivity_shifts_static_gyro_means_by_k_times_acc(truth, base):
    """``w_B += G a_B`` with a full matrix: the raw reading moves by ``K^-1 G a_B``."""
    effect = make_effect("g_sensitivity")
    on = render(truth, effect)
    g = np.asarray(effect.matrix)
    assert np.all(g != 0)  # cross-axis terms too
    k = np.linalg.solve(truth.calibration.gyr.matrix, g)
    for rec in ("cube", "static"):
        d = reading(on, rec, "gyr") - reading(base, rec, "gyr")
        acc = calibrated(base, rec, "acc")
        for seg in segs(on, rec, "position") + segs(on, rec, "static"):
            m = mask(on, rec, seg)
            # acc noise enters through k: k * sigma_acc / sqrt(n) is ~1e-8, negligible
            tol = count_tol(on, "gyr", m.sum())
            np.testing.assert_allclose(d[m].mean(axis=0), k @ acc[m].mean(axis=0), atol=tol)
    assert same_counts(on, base, sensors=("acc", "mag"))


def test_scale_nonlinearity_curves_the_rate_table_residual(truth, base):
    effect = make_effect("scale_nonlinearity", acc_k2=0.0, acc_k3=0.0)
    on = render(truth, effect)
    cal = truth.calibration.gyr
    full_scale = INT16_MAX * on.sensitivity["gyr"]
    d = reading(on, "ratetable", "gyr") - reading(base, "ratetable", "gyr")
    for axis in AXES:
        j = AXES.index(axis)
        rates, resid = [], []
        for seg in (s for s in segs(on, "ratetable", "run") if s.axis == axis):
            m = mask(on, "ratetable", seg)
            x = errormodel.invert(cal.matrix, np.zeros(3), np.radians(seg.rate_dps) * np.eye(3)[j])
            x = x / full_scale
            expected = full_scale * (effect.gyr_k2 * x**2 + effect.gyr_k3 * x**3)
            np.testing.assert_allclose(
                d[m].mean(axis=0), expected, atol=count_tol(on, "gyr", m.sum()), err_msg=seg.label
            )
            rates.append(seg.rate_dps)
            resid.append(d[m].mean(axis=0)[j])
        # curved in the rate: a straight line leaves residuals far above the rounding level
        line = np.polyval(np.polyfit(rates, resid, 1), rates)
        assert np.abs(np.asarray(resid) - line).max() > 20 * count_tol(on, "gyr", 700)
    # not elsewhere: zero input, zero change (the 0 deg/s runs and every static gyro sample)
    for rec, kind in (("cube", "position"), ("static", "static"), ("ratetable", "run")):
        for seg in segs(on, rec, kind):
            m = mask(on, rec, seg)
            if seg.rate_dps in (None, 0.0):
                np.testing.assert_array_equal(
                    on.logs[rec].counts["gyr"][m], base.logs[rec].counts["gyr"][m]
                )
    assert same_counts(on, base, sensors=("acc", "mag"))


def test_saturation_clips_the_gyro_at_250_dps(truth, base):
    on = render(truth, make_effect("saturation"))
    limit = make_effect("saturation").gyr
    assert np.abs(on.logs["ratetable"].counts["gyr"]).max() == limit
    assert on.dataset_dict()["range_counts"]["gyr"] == limit
    for seg in segs(on, "ratetable", "run"):
        m = mask(on, "ratetable", seg)
        j = AXES.index(seg.axis)
        c_on = on.logs["ratetable"].counts["gyr"][m, j]
        c_off = base.logs["ratetable"].counts["gyr"][m, j]
        if abs(seg.rate_dps) >= 300:  # 300 deg/s / scale 1.13-1.15 > 250 deg/s
            assert np.all(np.abs(c_on) == limit) and np.all(np.abs(c_off) > limit), seg.label
        elif abs(seg.rate_dps) <= 200:
            np.testing.assert_array_equal(c_on, c_off)
    assert same_counts(on, base, recs=("rotation3d", "cube", "static"))


# --- timing --------------------------------------------------------------------------------------


def test_time_offset_shifts_the_reference_only(truth, base):
    on = render(truth, make_effect("time_offset", offset_s=0.3))
    assert same_counts(on, base) and on.clock.offset_s == 0.3
    cols = ["Gyr_X", "Gyr_Y", "Gyr_Z"]
    w_on, w_off = on.reference[cols].to_numpy(), base.reference[cols].to_numpy()
    shift = 30  # 0.3 s at 100 Hz: the same event 30 rows later on the reference's axis
    n = len(w_off) - shift

    def rms(a, b):
        return float(np.sqrt(np.mean((a - b) ** 2)))

    sigma = truth.reference_noise["gyr"]
    assert rms(w_on[shift : shift + n], w_off[:n]) < 1.5 * math.sqrt(2) * sigma
    assert rms(w_on[:n], w_off[:n]) > 10 * sigma


def test_reference_jitter_moves_the_reference_samples_only(truth, base):
    jitter = make_effect("reference_jitter", std_s=2e-3)
    taken = jitter.on_reference_times(np.zeros(20000), stream_rng(1, "x"))
    assert np.std(taken) == pytest.approx(2e-3, rel=0.03) and abs(np.mean(taken)) < 1e-4
    on = render(truth, jitter)
    assert same_counts(on, base)
    stamps = ["PacketCounter", "SampleTimeFine"]
    np.testing.assert_array_equal(on.reference[stamps], base.reference[stamps])
    # where the rate changes the jittered samples differ from the nominal ones by about
    # omega_dot e (the reference's white noise is the same draw in both)
    cols = ["Gyr_X", "Gyr_Y", "Gyr_Z"]
    moved = np.abs(on.reference[cols].to_numpy() - base.reference[cols].to_numpy()).max(axis=1)
    assert 0 < np.count_nonzero(moved > 1e-9) < len(moved)


def test_packet_loss_leaves_seq_gaps_and_the_kept_rows_untouched(truth, base):
    on = render(truth, make_effect("packet_loss", fraction=0.02))
    for rec, log in on.logs.items():
        step = np.diff(log.seq) % 65536
        assert step.min() == 1 and np.count_nonzero(step > 1) > 0
        for s in SENSORS:
            np.testing.assert_array_equal(log.counts[s], base.logs[rec].counts[s][log.sample])


def test_timing_jitter_stamps_are_irregular_while_seq_stays_regular(truth, base):
    effect = make_effect("timing_jitter")
    on = render(truth, effect)
    assert same_counts(on, base)
    for log in on.logs.values():
        t, k = log.t_s, log.sample / RATE_HZ
        dt = np.diff(t)
        assert np.all(dt >= 0) and np.all(t >= k)  # receive after sampling, in order
        assert np.count_nonzero(dt == 0) > 0  # bursts share a stamp
        assert dt.std() > 0.5 * effect.std_s
        np.testing.assert_array_equal(np.diff(log.seq) % 65536, 1)
        # the counter gives strictly increasing sample times again (offset = mean latency)
        recovered = packet_times(t, log.seq)
        assert np.all(np.diff(recovered) > 0)
        assert np.abs(recovered - k - np.mean(t - k)).max() < 1e-3


# --- magnetometer -----------------------------------------------------------------------------


def test_mag_latency_lags_the_field_during_rotations_only(truth, base):
    effect = make_effect("mag_latency")
    on = render(truth, effect)
    assert same_counts(on, base, sensors=("acc", "gyr"))
    rec = "rotation3d"
    fresh = on.logs[rec].mag_fresh
    d = (calibrated(on, rec, "mag") - calibrated(base, rec, "mag"))[fresh]
    t = module_time(on, rec)[fresh]
    state = evaluate_motion(on.rendered[rec].motion, t)
    v = np.cross(state.omega_b, state.rotation.apply(truth.world.field, inverse=True))
    moving = np.zeros(len(t), bool)
    for seg in segs(on, rec, "phase"):
        moving |= (t >= seg.start_s) & (t < seg.end_s)
    # lag a: m(t - a) ~ m + a (w x m); least squares over the phases
    a = float(np.sum(d[moving] * v[moving]) / np.sum(v[moving] ** 2))
    resid = d[moving] - a * v[moving]
    sd = float(np.sqrt(np.mean(resid**2) / np.sum(v[moving] ** 2)))
    # the age of each reported value, from the realised phase of the magnetometer's clock; its
    # mean over all phases is the magnitude, delay + 1 / (2 rate)
    phase = on.realised["mag_latency"][rec]["phase_s"]
    held = phase + np.floor((t - effect.delay_s - phase) * effect.rate_hz) / effect.rate_hz
    age = t - held
    assert np.all((age >= effect.delay_s) & (age < effect.delay_s + 1 / effect.rate_hz))
    weights = np.sum(v[moving] ** 2, axis=1)
    expected = float(np.sum(age[moving] * weights) / weights.sum())
    assert abs(expected - effect.magnitude().value) <= 0.5 / effect.rate_hz
    # second order: m(t - a) - m(t) - a (w x m) ~ (a w)^2 / 2 ~ 3e-4 of |m|, ~1 % of the lag
    assert abs(a - expected) < 5 * sd + 0.02 * expected, (a, expected, sd)
    # static: only another noise sample is reported; its mean difference is noise
    sigma = np.linalg.norm(truth.calibration.mag.matrix, axis=1).max() * truth.noise["mag"]
    for seg in segs(on, rec, "static"):
        m = (t >= seg.start_s) & (t < seg.end_s)
        assert np.all(np.abs(d[m].mean(axis=0)) < 5 * math.sqrt(2) * sigma / math.sqrt(m.sum()))


def test_mag_latency_below_10_hz_repeats_reported_values(truth, base):
    on = render(truth, make_effect("mag_latency", rate_hz=4.0, delay_s=0.0))
    for session, (low, high) in ((on, (0.5, 0.7)), (base, (0.0, 0.01))):
        log = session.logs["static"]
        mag = log.counts["mag"][log.mag_fresh]
        repeats = np.mean(np.all(np.diff(mag, axis=0) == 0, axis=1))
        assert low <= repeats < high  # 4 Hz held, read at 10 Hz: 1 - 4/10 repeat


def test_platform_magnetic_makes_the_norm_depend_on_the_platform_angle(truth, base):
    effect = make_effect("platform_magnetic")
    on = render(truth, effect)
    assert same_counts(on, base, recs=("cube", "ratetable", "static"))
    assert same_counts(on, base, sensors=("acc", "gyr"))
    rec = "rotation3d"
    motion = on.rendered[rec].motion
    d = np.array([effect.field_x, effect.field_y, effect.field_z])
    fresh = on.logs[rec].mag_fresh
    sigma = np.linalg.norm(truth.calibration.mag.matrix, axis=1).max() * truth.noise["mag"]
    norms, expected_norms = [], []
    for session in (on, base):
        norm = np.linalg.norm(calibrated(session, rec, "mag"), axis=1)
        t = module_time(session, rec)
        per_pose = []
        for seg in segs(session, rec, "static"):
            m = fresh & (t >= seg.start_s) & (t < seg.end_s)
            psi = platform_yaw(motion, np.array([seg.start_s]))[0]
            with_d = truth.world.field + Rotation.from_euler("z", psi).apply(d)
            expected = np.linalg.norm(with_d) if session is on else 1.0
            if session is on:
                expected_norms.append(expected)
            assert abs(norm[m].mean() - expected) < 5 * sigma / math.sqrt(m.sum()), seg.label
            per_pose.append(norm[m].mean())
        norms.append(np.ptp(per_pose))
    # the transitions turn the platform by +-90 deg: |m| differs between poses
    np.testing.assert_allclose(
        platform_yaw(motion, np.array([s.end_s for s in segs(on, rec, "transition")])),
        [np.pi / 2, 0.0], atol=1e-12,
    )  # fmt: skip
    spread = np.ptp(expected_norms)  # |m_earth + d| vs |m_earth + Rz(90 deg) d|
    assert spread > 0.005  # about 25 times the 2e-4 noise of a pose's mean norm
    np.testing.assert_allclose(norms[0], spread, atol=0.002)
    assert norms[1] < 0.002


# --- kinematics ---------------------------------------------------------------------------------


def test_lever_arm_acc_grows_with_omega_squared_and_vanishes_static(truth, base):
    effect = make_effect("lever_arm")
    on = render(truth, effect)
    r = np.array([effect.x_m, effect.y_m, effect.z_m])
    d = calibrated(on, "ratetable", "acc") - calibrated(base, "ratetable", "acc")
    m_acc = truth.calibration.acc.matrix
    q = np.linalg.norm(m_acc, axis=1).max() * on.sensitivity["acc"]  # one count, calibrated
    for seg in segs(on, "ratetable", "run"):
        m = mask(on, "ratetable", seg)
        w = np.radians(seg.rate_dps) * np.eye(3)[AXES.index(seg.axis)]
        expected = np.cross(w, np.cross(w, r))  # centripetal, -w^2 r_perp
        np.testing.assert_allclose(d[m].mean(axis=0), expected, atol=5 * q / np.sqrt(m.sum()))
    assert same_counts(on, base, recs=("static",))
    for seg in segs(on, "cube", "position"):
        m = mask(on, "cube", seg)
        np.testing.assert_array_equal(
            on.logs["cube"].counts["acc"][m], base.logs["cube"].counts["acc"][m]
        )
    assert same_counts(on, base, sensors=("gyr", "mag"))


def test_earth_rotation_adds_the_projected_earth_rate_to_static_gyro(truth, base):
    effect = make_effect("earth_rotation")
    on = render(truth, effect)
    d = calibrated(on, "static", "gyr") - calibrated(base, "static", "gyr")
    pose = on.rendered["static"].motion.pieces[0].start
    lat = np.radians(effect.latitude_deg)
    expected = pose.apply(EARTH_RATE_RAD_S * np.array([np.cos(lat), 0, np.sin(lat)]), inverse=True)
    m_gyr = truth.calibration.gyr.matrix
    q = np.linalg.norm(m_gyr, axis=1).max() * on.sensitivity["gyr"]
    # 0.27 count per axis, dithered by the 5.6-count noise: the mean resolves it
    np.testing.assert_allclose(d.mean(axis=0), expected, atol=5 * q / np.sqrt(len(d)))
    assert np.linalg.norm(expected) == pytest.approx(7.2921150e-5)
    assert same_counts(on, base, sensors=("acc", "mag"))


# --- set-up -----------------------------------------------------------------------------------


def test_placement_error_turns_cube_positions_and_table_axes(truth, base):
    effect = make_effect("placement_error")
    on = render(truth, effect)
    assert on.truth_dict()["segments"] == base.truth_dict()["segments"]  # nominal segments
    assert same_counts(on, base, recs=("rotation3d", "static"))
    drawn = on.realised["placement_error"]
    a_on, a_off = calibrated(on, "cube", "acc"), calibrated(base, "cube", "acc")
    q = np.linalg.norm(truth.calibration.acc.matrix, axis=1).max() * on.sensitivity["acc"]
    deltas = []
    for seg in segs(on, "cube", "position"):
        m = mask(on, "cube", seg)
        delta = Rotation.from_rotvec(drawn["cube"][seg.label])
        deltas.append(delta.as_rotvec())
        mean_on, mean_off = a_on[m].mean(axis=0), a_off[m].mean(axis=0)
        # same noise in both: a_on = Exp(-delta) a_off up to the rounding (one count q)
        tol = 5 * q / np.sqrt(m.sum())
        np.testing.assert_allclose(mean_on, delta.inv().apply(mean_off), atol=tol)
        assert abs(np.linalg.norm(mean_on) - np.linalg.norm(mean_off)) < tol  # |a| unchanged
        assert np.linalg.norm(mean_on - mean_off) > 1e-3  # ~ g * tilt ~ 0.05 m/s^2
    # 36 draws: the std within the 99.9 % chi-square band of N(0, sigma)
    ratio = np.std(deltas) / np.radians(effect.cube_sigma_deg)
    assert 0.6 < ratio < 1.4, ratio
    # rate table: the spin axis in B is Exp(-delta_m) e_axis
    w = calibrated(on, "ratetable", "gyr")
    sigma = np.linalg.norm(truth.calibration.gyr.matrix, axis=1).max() * truth.noise["gyr"]
    for seg in segs(on, "ratetable", "run"):
        m = mask(on, "ratetable", seg)
        delta = Rotation.from_rotvec(drawn["ratetable"][seg.axis])
        nominal = np.radians(seg.rate_dps) * np.eye(3)[AXES.index(seg.axis)]
        tol = 5 * sigma / np.sqrt(m.sum())
        np.testing.assert_allclose(w[m].mean(axis=0), delta.inv().apply(nominal), atol=tol)


def test_large_misalignment_sets_alpha_and_only_the_small_angle_form_misses_it(truth, base):
    effect = make_effect("large_misalignment")
    on = render(truth, effect)
    for s in SENSORS:
        alpha = on.truth.calibration.sensor(s).decomposition.alpha_rad
        alpha0 = truth.calibration.sensor(s).decomposition.alpha_rad
        np.testing.assert_allclose(np.linalg.norm(alpha), np.radians(getattr(effect, f"{s}_deg")))
        np.testing.assert_allclose(alpha / np.linalg.norm(alpha), alpha0 / np.linalg.norm(alpha0))
        np.testing.assert_allclose(
            on.truth_dict()[s]["alpha"], alpha, atol=1e-12
        )  # truth.json holds the large angle
    # cube statics: exact truth gives |a| = g; the paper's small-angle matrix does not
    dec = on.truth.calibration.acc.decomposition
    small = errormodel.compose(dec.scale, dec.xi_rad, dec.alpha_rad, exact=False)
    raw = reading(on, "cube", "acc")
    g = truth.world.gravity_m_s2
    sigma = np.linalg.norm(on.truth.calibration.acc.matrix, axis=1).max() * truth.noise["acc"]
    theta = np.radians(effect.acc_deg)
    for seg in segs(on, "cube", "position"):
        m = mask(on, "cube", seg)
        exact_norm = np.linalg.norm(calibrated(on, "cube", "acc")[m], axis=1).mean()
        small_norm = np.linalg.norm(
            errormodel.apply(small, on.truth.calibration.acc.bias, raw[m]), axis=1
        ).mean()
        assert abs(exact_norm - g) < 5 * sigma / np.sqrt(m.sum())
        # I + [a]x stretches every vector by sqrt(1 + |a x v|^2) - 1, at most theta^2 / 2
        assert 0 <= small_norm - exact_norm < g * theta**2 / 2 + 5 * sigma / np.sqrt(m.sum())
    worst = max(
        np.linalg.norm(errormodel.apply(small, on.truth.calibration.acc.bias, raw[mask(on, "cube", s)]), axis=1).mean()
        - g
        for s in segs(on, "cube", "position")
    )  # fmt: skip
    assert worst > 0.3 * g * theta**2 / 2  # far above the 1e-3 m/s^2 noise of a position mean
    assert (
        dataclasses.replace(effect, acc_deg=0.0).on_truth(truth).calibration.acc
        == truth.calibration.acc
    )


# --- the harsh end of a consumer part and a module held by hand ------------------------------


def test_hand_tremor_moves_only_the_cube_holds_with_consistent_rate_and_attitude(truth, base):
    effect = make_effect("hand_tremor")
    on = render(truth, effect)
    assert same_counts(on, base, recs=("rotation3d", "ratetable", "static"))
    realised = on.realised["hand_tremor"]["cube"]
    positions = segs(on, "cube", "position")
    assert sorted(realised) == [s.label for s in positions]
    rate_rms = np.degrees([realised[s.label]["rate_rms_rad_s"] for s in positions])
    angle_rms = np.degrees([realised[s.label]["angle_rms_rad"] for s in positions])
    assert 0.5 < rate_rms.mean() < 2.0 and 0.1 < angle_rms.mean() < 1.0  # deg/s, deg per axis
    for seg in positions:
        m = mask(on, "cube", seg)
        gyr = calibrated(on, "cube", "gyr")[m]
        # the calibrated gyro's RMS is the realised tremor rate plus the white noise
        noise = np.linalg.norm(truth.calibration.gyr.matrix, axis=1) * truth.noise["gyr"]
        expected = np.hypot(realised[seg.label]["rate_rms_rad_s"], noise)
        np.testing.assert_allclose(np.sqrt((gyr**2).mean(axis=0)), expected, rtol=0.2)
        # the specific force turns with the hold: integrate the true rate, rotate gravity
        state = evaluate_motion(on.rendered["cube"].motion, module_time(on, "cube")[m])
        angle = (state.rotation[0].inv() * state.rotation).magnitude()
        acc = calibrated(on, "cube", "acc")[m]
        g = state.rotation.apply(truth.world.specific_force, inverse=True)
        sigma = np.linalg.norm(truth.calibration.acc.matrix, axis=1).max() * truth.noise["acc"]
        assert np.abs(acc - g).mean() < 2 * sigma  # residual is the noise only
        assert np.degrees(angle.max()) > 0.2  # it did move
    # the nominal plan is kept; the rendered holds start and end on the nominal orientations
    for nominal, rendered in zip(on.plans["cube"].motion.pieces, on.rendered["cube"].motion.pieces):
        assert (nominal.start.inv() * rendered.start).magnitude() < 1e-12
    with pytest.raises(ValueError, match="tremor band must satisfy"):
        make_effect("hand_tremor", tremor_min_hz=12.0, tremor_max_hz=4.0)


def test_temperature_drift_at_the_harsh_end_of_a_consumer_part(truth, base):
    # MPU-9250 spreads: gyro 0.24 deg/s/K, accelerometer 1.5 mg/K; a 15 K warm-up
    effect = make_effect(
        "temperature_drift", gyr_per_k=4.4e-3, acc_per_k=0.0196, rise_c=15.0, tau_s=300.0
    )
    on = render(truth, effect)
    dT = on.logs["static"].extra["temp_c"] - effect.start_c
    assert dT.max() > 10.0
    for sensor in ("gyr", "acc"):
        d = reading(on, "static", sensor) - reading(base, "static", sensor)
        k, scale = effect.coefficients(sensor)
        n = len(d)
        tol = count_tol(on, sensor, n) + k * 0.005
        if sensor == "acc":  # the scale drift multiplies g on the up axis
            u = errormodel.invert(truth.calibration.acc.matrix, np.zeros(3),
                                  np.array([[0.0, 0.0, truth.world.gravity_m_s2]]))[0]  # fmt: skip
            expected = (k + scale * u) * dT.mean()
        else:  # at rest the gyro's input is zero: the scale drift does not show
            expected = k * dT.mean()
        assert np.all(np.abs(d.mean(axis=0) - expected) <= tol), (sensor, expected)
    assert all(c == 0 for rec in on.clipped.values() for c in rec.values())


def test_bias_random_walk_of_the_stress_set_wanders_by_rw_sqrt_t():
    # gyr_rw 2e-4 rad/s/sqrt(s): after 600 s the RMS change is 4.9e-3 rad/s (0.28 deg/s)
    rw, horizon = 2e-4, 600.0
    effect = make_effect("bias_instability", gyr_rw=rw, gyr_gm=0.0, acc_rw=0.0, acc_gm=0.0)
    change = np.vstack([
        np.diff(effect.bias(np.array([0.0, horizon]), 10.0, seed)["gyr"], axis=0)
        for seed in range(60)
    ])  # fmt: skip
    # 180 draws: the RMS to ~5 %, allow 15 %
    np.testing.assert_allclose(np.sqrt((change**2).mean()), rw * np.sqrt(horizon), rtol=0.15)
    assert np.degrees(rw * np.sqrt(horizon)) == pytest.approx(0.28, abs=0.01)


def test_large_misalignment_of_8_deg_on_a_mems_truth_fits_int16():
    effect = make_effect("large_misalignment", acc_deg=8.0, gyr_deg=8.0, mag_deg=8.0)
    truth = effect.on_truth(make_truth("mems", stream_rng(SEED, "truth")))
    for s in SENSORS:
        alpha = truth.calibration.sensor(s).decomposition.alpha_rad
        np.testing.assert_allclose(np.linalg.norm(alpha), np.radians(8.0))
    on = simulate_session(truth, SEED, CONFIG)
    assert on.clipped["ratetable"]["gyr"] == 0
    peak = np.abs(reading(on, "ratetable", "gyr")).max()
    assert np.degrees(peak) > 400 / 1.2 and peak / on.sensitivity["gyr"] < INT16_MAX


def test_world_magnetic_adds_a_field_that_follows_the_position_not_the_attitude(truth, base):
    effect = make_effect("world_magnetic")
    on = render(truth, effect)
    assert same_counts(on, base, sensors=("acc", "gyr"))
    t = module_time(on, "rotation3d")
    state = evaluate_motion(on.rendered["rotation3d"].motion, t)
    # in the world, the added field is G p with p = R r the sensor's position from the pivot
    added_world = state.rotation.apply(
        calibrated(on, "rotation3d", "mag") - calibrated(base, "rotation3d", "mag")
    )
    fresh = np.isfinite(added_world[:, 0])
    expected = state.rotation.apply(effect.arm())[fresh] @ effect.gradient().T
    step = np.abs(truth.calibration.mag.matrix).sum(axis=1).max() * on.sensitivity["mag"]
    # two roundings of one count, through the calibration matrix
    assert np.abs(added_world[fresh] - expected).max() < 2 * step
    assert np.sqrt((expected**2).sum(axis=1).mean()) > 0.5 * effect.magnitude().value
    np.testing.assert_allclose(np.trace(effect.gradient()), 0.0, atol=1e-15)


def test_shock_adds_half_sine_pulses_at_the_recorded_times_only(truth, base):
    effect = make_effect("shock", rate_per_s=0.5)
    on = render(truth, effect)
    assert same_counts(on, base, sensors=("mag",))
    times = np.array(on.realised["shock"]["static"]["times_s"])
    t = module_time(on, "static")
    # about rate x duration knocks (Poisson: 5 sigma)
    assert abs(len(times) - 0.5 * np.ptp(t)) < 5 * np.sqrt(0.5 * np.ptp(t))
    added = reading(on, "static", "gyr") - reading(base, "static", "gyr")
    inside = np.zeros(len(t), dtype=bool)
    step = on.sensitivity["gyr"]
    for t0 in times:
        knock = (t >= t0) & (t < t0 + effect.duration_s + 1 / RATE_HZ)
        inside |= knock
        # the readings' integral is the half-sine's, 2 A D / pi, up to a count per sample
        impulse = np.linalg.norm(added[knock].sum(axis=0)) / RATE_HZ
        expected = 2 * effect.gyr_peak_rad_s * effect.duration_s / np.pi
        assert abs(impulse - expected) <= 2 * knock.sum() * step / RATE_HZ, t0
    assert np.abs(added[~inside]).max() <= 1.01 * step
    assert np.linalg.norm(added[inside], axis=1).max() <= effect.gyr_peak_rad_s + 2 * step
    with pytest.raises(ValueError, match="shock rate_per_s must be > 0"):
        make_effect("shock", rate_per_s=0.0)


def test_vibration_is_a_line_at_its_frequency_in_acc_and_gyro(truth, base):
    effect = make_effect("vibration")
    on = render(truth, effect)
    assert same_counts(on, base, sensors=("mag",))
    t = module_time(on, "static")
    for sensor, amp in (("gyr", effect.gyr_amp_rad_s), ("acc", effect.acc_amp_m_s2)):
        added = reading(on, "static", sensor) - reading(base, "static", sensor)
        direction = np.array(on.realised["vibration"]["static"][f"direction_{sensor}"])
        phase = on.realised["vibration"]["static"]["phase_rad"]
        wave = amp * np.sin(2 * np.pi * effect.freq_hz * t + phase)
        assert np.abs(added - wave[:, None] * direction).max() <= 1.01 * on.sensitivity[sensor]
    with pytest.raises(ValueError, match="vibration freq_hz must be > 0 Hz"):
        make_effect("vibration", freq_hz=-1.0)
