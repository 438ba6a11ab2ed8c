"""The gap diagnosis: its null (false-alarm rate) and each effect estimator's signature."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats as sps

from imucal.gap.effects import Estimate
from imucal.gap.library import scope_library
from imucal.gap.null import NullModel, build_null, holm, run_replicas, total_gap
from imucal.gap.scoring import verdict_of
from imucal.gap.statistics import compute_statistics
from imucal.gap.twin import build_twin, render_replica
from imucal.pipeline.full import PipelineOptions, calibrate_session
from imucal.sim import ProtocolConfig, make_effect, make_truth
from imucal.sim.effects import stream_rng
from imucal.sim.session import SENSITIVITY

SHORT = ProtocolConfig(static_s=60.0, run_plateau_s=3.0, run_pause_s=1.5)
RANGE = {"acc": 32767, "gyr": 32767, "mag": 32767}
RATETABLE = {"axes": list(SHORT.ratetable_axes), "rates_dps": list(SHORT.rates_dps)}


@pytest.fixture(scope="module")
def twin():
    """A twin built from a clean simulated session (fit by the same in-process pipeline)."""
    from imucal.gap.twin import TWIN_RECORDINGS, Twin

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
    return scope_library("protocol")[name].estimate(fit, half), fit


@pytest.mark.parametrize(
    ("name", "params", "check"),
    [
        ("packet_loss", {"fraction": 0.01, "model": "bernoulli"}, lambda p: p["fraction"]),
        ("time_offset", {"offset_s": 0.2}, lambda p: p["offset_s"]),
        ("lever_arm", {"x_m": 0.05, "y_m": -0.03, "z_m": 0.02},
         lambda p: np.array([p["x_m"], p["y_m"], p["z_m"]])),
        ("g_sensitivity",
         {"matrix": [[5e-4, 1.5e-4, 0.0], [-1e-4, -3e-4, 8e-5], [6e-5, -1.2e-4, 2e-4]]},
         lambda p: np.array(p["matrix"])),
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


def test_a_candidate_is_evaluated_as_the_joint_model_with_the_accepted_ones():
    """'a' closes location 0, 'b' location 1, each alone. Their shifts added close both, so
    both are accepted; rendered together (joint_shifts) they close only location 0 (the
    second does not add where the first already acts): 'b' is then not accepted, and the
    joint model is what the remaining shift is."""
    from imucal.gap.attribution import Candidate, select_forward

    keys = [("s", "gyr", ax, "all", "resid_rms") for ax in "xyz"]
    rng = np.random.default_rng(2)
    null = NullModel.from_values(keys, rng.normal(0, 0.01, (20, 3)))
    values = dict(zip(keys, np.exp([0.5, 0.5, 0.0]), strict=True))
    stats = {h: dict(values) for h in (None, "A", "B")}
    closes = {"a": [0], "b": [1]}

    def shifts_of(c):
        shift = {keys[i]: (0.5, 0.0) for i in closes[c.name]}
        return shift, shift

    def run(joint_shifts):
        cands = [Candidate(n, {"p": 1}, {"p": 1}, 1.0, 10.0) for n in closes]
        return select_forward(
            cands, stats, null, null, shifts_of, alpha=0.05, min_heldout_shrink=0.3,
            detect_z=4.0, joint_shifts=joint_shifts,
        )  # fmt: skip

    explained, shift, *_ = run(None)
    assert sorted(explained) == ["a", "b"] and set(shift) == {keys[0], keys[1]}
    together = {keys[0]: (0.5, 0.0)}
    explained, shift, *_ = run(lambda group: (together, together))
    assert len(explained) == 1 and shift == together


def test_an_effect_beyond_its_null_on_its_own_is_evaluated_without_a_location_in_the_gap():
    """The Earth's rate spreads over the north and up components of the world-fixed rate: each
    is about 3.5 null std out, which Holm over 60 locations does not flag (t(11) needs about
    4.6), while the effect's own estimator (their norm) is 6 null std out. The candidate whose
    own statistic is beyond its null (one-sided, corrected for the library) is evaluated and,
    as it closes the gap held out, accepted; one that is not is never evaluated, and neither
    is any candidate when no statistic is beyond its null."""
    from imucal.gap.attribution import Candidate, evident_on_its_own, select_forward

    keys = [("s", "gyr", f"a{i}", "rest", "world_rate") for i in range(60)]
    rng = np.random.default_rng(4)
    null = NullModel.from_values(keys, rng.normal(0.0, 1.0, (12, len(keys))))
    spread = null.scale
    # the other locations at |t| = 1.2, a little above the null's mean t^2 of 11/9
    signs = np.where(np.arange(len(keys)) % 2, 1.0, -1.0)
    values = dict(zip(keys, null.mean + 1.2 * signs * spread, strict=True))
    values[keys[0]] = null.mean[0] + 3.5 * spread[0]
    values[keys[1]] = null.mean[1] + 3.5 * spread[1]
    stats = {h: dict(values) for h in (None, "A", "B")}
    assert not holm(null.p_values(null.t(stats[None])), 0.05).any()

    def shifts_of(c):
        shift = {k: (3.5 * spread[i], 0.0) for i, k in enumerate(keys[:2])}
        return shift, shift

    def run(evident):
        c = Candidate("earth_rotation", {"p": 1}, {"p": 1}, 1.0, 6.0, evident=evident)
        out = select_forward(
            [c], stats, null, null, shifts_of, alpha=0.05, min_heldout_shrink=0.3,
            detect_z=4.0,
        )  # fmt: skip
        return out[0], c

    explained, c = run(True)
    assert explained == ["earth_rotation"] and c.heldout_shrink > 0.5
    explained, c = run(False)
    assert explained == [] and not c.evaluated
    # one-sided (an effect raises its statistic), Bonferroni over 12 estimates, t(11)
    assert evident_on_its_own(6.0, 12, 12, 0.05, 4.0)
    assert not evident_on_its_own(-10.0, 12, 12, 0.05, 4.0)
    assert not evident_on_its_own(3.9, 12, 12, 0.05, 4.0)
    assert evident_on_its_own(3.1, 12, 1, 0.05, 3.0)
    assert not evident_on_its_own(3.1, 12, 12, 0.05, 3.0)  # t(11) at 0.05 / 12 is 3.2
    assert not evident_on_its_own(float("nan"), 12, 12, 0.05, 4.0)


def test_a_candidate_is_scored_against_the_null_of_the_accepted_effects():
    """A lever arm's statistic (|r|, 1e-5 m null spread) at 4.6e-5 m is 4.4 null std out of
    the clean null, but a wandering bias accepted before it moves the rate-table means by
    as much: rendered with the same seeds with and without the wander, |r| changes by
    3.5e-5 m on average with a spread of 2e-5 m between seeds. Against that null it is
    0.4 out, so the candidate only takes the wander's residual and is not evaluated; a
    lever arm of 0.5 mm stays beyond it. Before anything is accepted the candidate is
    scored as before."""
    from imucal.gap.attribution import Candidate, detection_z_given, select_forward

    rng = np.random.default_rng(3)
    null_values = list(rng.normal(0.0, 1e-5, 8))
    without = null_values[:3]
    with_wander = [v + d for v, d in zip(without, (1.5e-5, 3.5e-5, 5.5e-5), strict=True)]
    assert abs(detection_z_given(4.6e-5, null_values, with_wander, without)) < 1.0
    assert detection_z_given(5e-4, null_values, with_wander, without) > 10
    assert np.isnan(detection_z_given(4.6e-5, null_values, with_wander[:1], without[:1]))

    keys = [("s", "acc", ax, "run", "resid_rms") for ax in "xyz"]
    null = NullModel.from_values(keys, rng.normal(0, 0.01, (20, 3)))
    values = dict(zip(keys, np.exp([0.5, 0.5, 0.0]), strict=True))
    stats = {h: dict(values) for h in (None, "A", "B")}

    def shifts_of(c):
        shift = {keys[0 if c.name == "bias_instability" else 1]: (0.5, 0.0)}
        return shift, shift

    def run(z_lever):
        cands = [Candidate("bias_instability", {"p": 1}, {"p": 1}, 1.0, 20.0),
                 Candidate("lever_arm", {"p": 1}, {"p": 1}, 1.0, 4.4)]  # fmt: skip
        explained, *_ = select_forward(
            cands, stats, null, null, shifts_of, alpha=0.05, min_heldout_shrink=0.3,
            detect_z=4.0, z_given=lambda c, accepted: z_lever,
        )  # fmt: skip
        return explained, cands[1]

    explained, lever = run(0.4)
    assert explained == ["bias_instability"] and not lever.evaluated
    assert "null of the twin with bias_instability" in lever.note
    explained, lever = run(12.0)
    assert explained == ["bias_instability", "lever_arm"]


def test_an_effect_with_its_own_evidence_is_judged_beside_what_the_twin_does_not_replay():
    """A recording with an optical reference: the reference's error the twin does not replay
    puts rate3 at z 100, while a magnet fixed in the world puts field_dipole_peak at z 15 and
    the field direction at z 20. Rendering the magnet closes its two locations, 0.06 of the
    whole gap; judged where it acts (its own locations: it moves nothing else) it closes all of
    it and is accepted, and so judged beside what the twin does not replay (the reference's
    error, the field's uniformity) with its own locations. On a control, with only the field
    direction in the gap (the reference's error carries the field into the world too) and the
    dipole within its null, it has no evidence of its own outside the shortfalls: judged on
    the whole gap, and refused."""
    from imucal.gap.attribution import Candidate, judged_locations, select_forward
    from imucal.gap.effects import EffectModel
    from imucal.gap.scoring import unreplayed
    from imucal.gap.statistics import CATALOGUE

    keys = [("reference", "gyr", "x", "tumble", "rate3"),
            ("reference", "mag", "-", "tumble", "field_dipole_peak"),
            ("reference", "mag", "-", "tumble", "dir_resid_rad"),
            ("reference", "gyr", "x", "tumble", "ref_g_slope")]  # fmt: skip
    magnet = EffectModel("world_magnetic", None, (("reference", "mag", "field_dipole_peak"),
                                                  ("reference", "mag", "dir_resid_rad")), "a magnet")  # fmt: skip
    assert [unreplayed(k) for k in keys] == [True, False, True, False]
    # only the reference comparison's shortfalls: a static part keeps its own judgement
    assert not unreplayed(("noise", "gyr", "x", "static", "adev_10s_excess"))
    rng = np.random.default_rng(5)
    null = NullModel.from_values(keys, rng.normal(0.0, 1.0, (20, len(keys))))

    def run(z, beside):
        scored = null.mean + np.asarray(z) * null.scale  # transformed units
        raw = [np.exp(v) if CATALOGUE[k[4]].log else v for k, v in zip(keys, scored, strict=True)]
        stats = {h: dict(zip(keys, raw, strict=True)) for h in (None, "A", "B")}
        closes = {k: (z[i] * null.scale[i], 0.0) for i, k in enumerate(keys) if magnet.matches(k)}
        c = Candidate("world_magnetic", {"p": 1}, {"p": 1}, 1.0, 40.0)
        explained, *_ = select_forward(
            [c], stats, null, null, lambda c: (closes, closes), alpha=0.05,
            min_heldout_shrink=0.3, detect_z=4.0, unreplayed=unreplayed if beside else None,
            own={"world_magnetic": magnet.matches},
        )  # fmt: skip
        return explained, c

    explained, c = run([100.0, 15.0, 20.0, 3.0], beside=False)
    assert explained == ["world_magnetic"] and c.judged is None and c.heldout_shrink > 0.9
    explained, c = run([100.0, 15.0, 20.0, 3.0], beside=True)
    assert explained == ["world_magnetic"] and c.judged is not None and c.heldout_shrink > 0.9
    explained, c = run([100.0, 1.0, 20.0, 3.0], beside=True)
    assert explained == [] and c.judged is None and c.heldout_shrink < 0.1
    assert judged_locations(magnet.matches, keys[:1], unreplayed) is None
    assert judged_locations(magnet.matches, keys[1:2], None) is None


def test_a_latency_is_one_delay_in_every_phase():
    """The lag of the magnetometer in each phase, null spread 1.5 ms per phase (the stress
    sessions' replicas): a 20 ms delay read with that noise passes the latency gate in 200
    draws but for the gate's two-sided tail at z = 4 (F(2, 7) at 6e-5: about 1 in 16000);
    lags of either sign as a field that moves with the platform leaves (-37, +60, +75 ms)
    are refused, and so is a common delay beside one phase 25 null spreads off (F(2, 7) is
    heavy-tailed: 10 spreads, p = 4e-4, still pass)."""
    rng = np.random.default_rng(7)
    s = 0.0015
    null = [Estimate({}, 0.0, {"lag_s": list(rng.normal(0, s, 3))}) for _ in range(8)]
    gate = scope_library("protocol")["mag_latency"].gate
    refused = sum(
        bool(gate(Estimate({}, 0.02, {"lag_s": list(0.02 + rng.normal(0, s, 3))}),
                  null, 4.0))
        for _ in range(200)
    )  # fmt: skip
    assert refused == 0
    platform = Estimate({}, 0.033, {"lag_s": [-0.037, 0.060, 0.075]})
    assert "disagree with one delay" in gate(platform, null, 4.0)
    one_off = Estimate({}, 0.025, {"lag_s": [0.02, 0.02, 0.02 + 25 * s]})
    assert gate(one_off, null, 4.0)
    # without the phases' lags (or without a null) there is nothing to refuse on
    assert gate(Estimate({}, 0.02), null, 4.0) == ""
    assert gate(platform, null[:2], 4.0) == ""


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


def test_total_gap_is_the_excess_over_the_nulls_mean():
    """Scores of a true null (t with df dof) add up to L df / (df - 2) on average, so the gap,
    their excess over it floored at 0, is 0 for about half of the draws; one location 10
    sigma out among quiet ones leaves its 100 less the null's mean."""
    rng = np.random.default_rng(3)
    df, n_loc = 11, 60
    draws = sps.t.rvs(df, size=(4000, n_loc), random_state=rng)
    sums = np.sum(draws**2, axis=1)
    assert sums.mean() == pytest.approx(n_loc * df / (df - 2), rel=0.02)
    gaps = np.array([total_gap(t, df) for t in draws])
    assert 0.3 < np.mean(gaps == 0) < 0.7
    lone = np.zeros(n_loc)
    lone[0] = 10.0
    assert total_gap(lone, df) == pytest.approx(100 - n_loc * df / (df - 2))
    lone[1] = np.nan  # a location without a score does not count
    assert total_gap(lone, df) == pytest.approx(100 - (n_loc - 1) * df / (df - 2))
    with pytest.raises(ValueError, match="degrees of freedom"):
        total_gap(draws[0], 2)


def test_deviance_charges_an_effect_for_the_spread_it_adds():
    """A location 20 sigma out: a shift of its mean closes the gap and the deviance; a shift
    that only widens the null by the same 20 sigma closes the gap as well but keeps a
    deviance of log(1 + 400), so the mean shift ranks first."""
    keys = [("s", "x", "-", "-", "temp_slope"), ("s", "y", "-", "-", "temp_slope")]
    rng = np.random.default_rng(4)
    null = NullModel.from_values(keys, rng.standard_normal((30, 2)))
    session = {keys[0]: float(null.mean[0] + 20 * null.scale[0]), keys[1]: float(null.mean[1])}
    assert null.gap(session) > 300
    mean_shift = {keys[0]: (20 * null.scale[0], 0.0)}
    widening = {keys[0]: (0.0, (20 * null.scale[0]) ** 2)}
    assert null.gap(session, mean_shift) == 0.0
    assert null.gap(session, widening) == 0.0
    assert null.deviance(session, mean_shift) < 1.0
    assert null.deviance(session, widening) == pytest.approx(1 + np.log(401), rel=0.01)


def test_a_location_whose_replicas_are_all_equal_has_no_score():
    """A statistic without a resolution floor that every replica gives alike (a trend of a
    reading that never changes) has no spread to score against: any departure, however small,
    would be infinitely significant. It is left unscored and named."""
    keys = [
        ("noise", "gyr", "x", "static", "trend_per_s"),
        ("noise", "gyr", "y", "static", "trend_per_s"),
    ]
    rng = np.random.default_rng(2)
    null = NullModel.from_values(keys, np.column_stack([np.zeros(20), rng.standard_normal(20)]))
    assert null.constant == [keys[0]]
    t = null.t({keys[0]: 1e-12, keys[1]: 0.0})
    assert np.isnan(t[0]) and np.isfinite(t[1])
    assert not holm(null.p_values(t), 0.05).any()
    assert np.all(np.isfinite(null.leave_one_out_gaps()))


def test_the_null_95th_percentile_is_positive_where_resolution_floors_dominate():
    """30 locations whose replicas scatter by a tenth of their floor (ref_scale, floor 1e-4)
    and 4 noise-dominated ones: charging every location the full null mean of t^2 leaves
    every replica's leave-one-out gap at 0 (a null 95th percentile of 0, so any session is
    'significant'); charging each its share of spread does not."""
    rng = np.random.default_rng(3)
    floored = [("reference", "gyr", "x", f"r{k}", "ref_scale") for k in range(30)]
    noisy = [("reference", "gyr", "x", f"r{k}", "rate3") for k in range(4)]
    values = np.hstack([1.0 + 1e-5 * rng.standard_normal((20, 30)), rng.standard_normal((20, 4))])
    null = NullModel.from_values(floored + noisy, values)
    assert null.spread_share[:30].max() < 0.05 and np.all(null.spread_share[30:] == 1.0)
    loo = null.leave_one_out_gaps()
    assert np.percentile(loo, 95) > 0
    unweighted = []
    for i in range(20):
        rest = NullModel.from_values(floored + noisy, np.delete(values, i, axis=0))
        unweighted.append(total_gap((values[i] - rest.mean) / rest.scale, rest.df))
    assert np.percentile(unweighted, 95) == 0.0


def _result(significant, effects=(), remaining=()):
    def loc(stage, sensor, statistic, z):
        return {
            "stage": stage,
            "sensor": sensor,
            "axis": "x",
            "segment": "r",
            "statistic": statistic,
            "z": z,
            "in_gap": True,
        }

    rem = [loc(*r) for r in remaining]
    return {
        "gap": {"total": 50.0 if significant else 0.0, "null_p95": 3.0, "significant": significant},
        "effects": [
            {"name": n, "accepted": True, "heldout_shrink": s, "params": {}} for n, s in effects
        ],
        "remaining": {"significant": bool(rem), "locations": rem},
    }


def test_the_verdict_tells_a_clean_session_an_effect_and_a_shortfall_of_the_twin():
    assert verdict_of(_result(False))["outcome"] == "nothing beyond the model"
    found = verdict_of(_result(True, [("g_sensitivity", 0.8)]))
    assert found["outcome"] == "effect"
    assert found["sentence"] == "Effect g_sensitivity (physical), shrink 80.0% held out."
    assert verdict_of(_result(True, [("timing_jitter", 0.998)]))["effects"][0]["kind"] == (
        "acquisition"
    )
    # a magnet judged beside the reference's error, which the twin still lacks
    beside = _result(True, [("world_magnetic", 0.52)],
                     remaining=[("reference", "gyr", "rate3", 138.0)])  # fmt: skip
    beside["effects"][0]["judged_beside_shortfalls"] = True
    assert verdict_of(beside)["sentence"] == (
        "Effect world_magnetic (physical), shrink 52.0% held out, judged beside what the twin "
        "lacks; the twin still lacks the reference's error beyond white noise (smoothing, "
        "latency, glitches) (at reference/gyr/x/r rate3 (z = 138))."
    )
    # the gap in the reference comparison's rate curvature, no effect accepted: the reference
    lacks = verdict_of(_result(True, remaining=[("reference", "gyr", "rate3", 300.0),
                                                ("reference", "mag", "dir_resid_rad", 20.0)]))  # fmt: skip
    assert lacks["outcome"] == "twin lacks"
    assert [g["what"] for g in lacks["lacks"]] == [
        "the reference's error beyond white noise (smoothing, latency, glitches)",
        "a uniform magnetic field",
    ]
    assert lacks["lacks"][0]["share"] == pytest.approx(300**2 / (300**2 + 20**2))
    # an accepted reference effect names the reference, not a physical effect
    jitter = verdict_of(_result(True, [("reference_jitter", 0.6)]))
    assert jitter["outcome"] == "twin lacks" and jitter["effects"] == []
    assert "reference_jitter shrinks the gap 60.0% held out" in jitter["sentence"]
    # a gap in a physical response no effect closes: an effect the library does not hold
    other = verdict_of(_result(True, remaining=[("temperature", "gyr", "temp_slope", 9.0)]))
    assert other["lacks"][0]["what"] == "an effect the library does not hold"
