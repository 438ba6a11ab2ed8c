"""The gap diagnosis: its null (false-alarm rate) and each effect estimator's signature."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats as sps

from imucal.gap import effects as gap_effects
from imucal.gap.null import build_null, holm, run_replicas
from imucal.gap.pipeline import PipelineOptions, calibrate_session
from imucal.gap.statistics import compute_statistics
from imucal.gap.twin import build_twin, render_replica
from imucal.sim import ProtocolConfig, make_effect, make_truth
from imucal.sim.effects import stream_rng
from imucal.sim.session import SENSITIVITY

SHORT = ProtocolConfig(static_s=60.0, run_plateau_s=3.0, run_pause_s=1.5)
RANGE = {"acc": 32767, "gyr": 32767, "mag": 32767}
RATETABLE = {"axes": list(SHORT.ratetable_axes), "rates_dps": list(SHORT.rates_dps)}


@pytest.fixture(scope="module")
def twin():
    """A twin built from a clean simulated session (fit by the same in-process pipeline)."""
    from imucal.gap.twin import Twin, TWIN_RECORDINGS

    truth = make_truth("paper", stream_rng(0, "truth"))
    options = PipelineOptions(9.81, SENSITIVITY, RANGE, RATETABLE)
    base = Twin(truth, SHORT, options, TWIN_RECORDINGS, True)
    imu, ref = render_replica(base, 7)
    fit = calibrate_session(imu, ref, options)
    return build_twin(fit, options), fit


def test_twin_noise_matches_the_session(twin):
    tw, _ = twin
    # std of the robust std estimate over ~20k differences is < 2 %; the gyro LSB is 18 % of sigma
    for s, true in {"acc": 0.020, "gyr": 0.0015, "mag": 0.004}.items():
        assert tw.truth.noise[s] == pytest.approx(true, rel=0.1), s


def test_null_false_alarm_rate_is_nominal(twin):
    """Each replica scored against the others is a draw from the null: the fraction with a
    location in the gap must be consistent with alpha (binomial 1 % upper bound)."""
    tw, _ = twin
    reps = run_replicas(tw, 24, seed=300)
    null = build_null(reps, None)
    alpha = 0.05
    flags = null.leave_one_out_flags(alpha)
    bound = sps.binom.ppf(0.99, len(flags), alpha)
    assert flags.sum() <= bound, (flags.sum(), bound)
    # and a fresh, independent replica is not in the gap at more than the same rate
    fresh = run_replicas(tw, 6, seed=900)
    hits = sum(bool(holm(null.p_values(null.t(r.stats[None])), alpha).any()) for r in fresh)
    assert hits <= sps.binom.ppf(0.99, 6, alpha) + 1


def _estimate(tw, name, effect, seed=11, half=None):
    imu, ref = render_replica(tw, seed, (effect,) if effect else ())
    fit = calibrate_session(imu, ref, tw.options)
    return gap_effects.LIBRARY[name].estimate(fit, half), fit


@pytest.mark.parametrize(
    ("name", "params", "check"),
    [
        ("packet_loss", {"fraction": 0.01, "model": "bernoulli"}, lambda p: p["fraction"]),
        ("time_offset", {"offset_s": 0.2}, lambda p: p["offset_s"]),
        ("lever_arm", {"x_m": 0.05, "y_m": -0.03, "z_m": 0.02},
         lambda p: np.array([p["x_m"], p["y_m"], p["z_m"]])),
        ("g_sensitivity", {"kx": 5e-4, "ky": -3e-4, "kz": 2e-4},
         lambda p: np.array([p["kx"], p["ky"], p["kz"]])),
        ("timing_jitter", {"std_s": 0.003}, lambda p: p["std_s"]),
    ],
)  # fmt: skip
def test_effect_estimator_recovers_its_parameters(twin, name, params, check):
    tw, _ = twin
    est, _ = _estimate(tw, name, make_effect(name, **params))
    null, _ = _estimate(tw, name, None)
    got, true, zero = check(est.params), check(params), check(null.params)
    # the effect's estimate is near the truth and far from the same estimator without it
    assert np.allclose(got, true, rtol=0.25, atol=0.1 * np.max(np.abs(true))), (got, true)
    assert np.max(np.abs(np.subtract(got, zero))) > 0.5 * np.max(np.abs(true))


def test_lever_arm_signature_is_centripetal_only(twin):
    """A lever arm moves the acc rate^2 statistics and not the gyro resting statistics."""
    tw, _ = twin
    reps = run_replicas(tw, 8, seed=500)
    null = build_null(reps, None)
    _, fit = _estimate(tw, "lever_arm", make_effect("lever_arm", x_m=0.05, y_m=0.04, z_m=0.0))
    t = null.t(compute_statistics(fit, None))
    hit = holm(null.p_values(t), 0.05)
    flagged = {k[4] for k, h in zip(null.keys, hit, strict=True) if h}
    assert "omega2" in flagged
    assert not flagged & {"g_slope", "vertical", "loss_fraction", "ref_offset_s"}
