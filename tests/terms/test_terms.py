"""Model terms: recovery of simulated coefficients within 3 reported standard deviations, the
held-out improvement on a second session of the same unit, the switch per term, byte identity
of auto and off on a clean session, the file format and apply's refusals."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from imucal.calibration import ImuCalibration
from imucal.columns import ACC, GYR, MAG, SENSORS, SI_COLUMN_UNITS
from imucal.gap import session as st
from imucal.gap.twin import TWIN_RECORDINGS, Twin, render_replica
from imucal.modelterms import (
    LeverArm,
    ModelTerms,
    TemperaturePolynomial,
    TemperatureTerm,
    settings_schema,
)
from imucal.pipeline.full import PipelineOptions, calibrate_session
from imucal.pipeline.stages import apply_calibration, calibration_of_what_ran
from imucal.sim import ProtocolConfig, make_effect, make_truth
from imucal.sim.effects import stream_rng
from imucal.sim.session import RATE_HZ, SENSITIVITY, simulate_session
from imucal.terms import (
    TermSettings,
    close_loop,
    corrected_session,
    decide,
    final_calibration,
    terms_summary,
)

SHORT = ProtocolConfig(static_s=120.0, run_plateau_s=3.0, run_pause_s=1.5)
RANGE = {"acc": 32767, "gyr": 32767, "mag": 32767}
RATETABLE = {"axes": list(SHORT.ratetable_axes), "rates_dps": list(SHORT.rates_dps)}
ON = TermSettings.only("on")

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def twin():
    truth = make_truth("paper", stream_rng(0, "truth"))
    options = PipelineOptions(9.81, SENSITIVITY, RANGE, RATETABLE)
    return Twin(truth, SHORT, options, TWIN_RECORDINGS, True)


def _loop(twin, seed, effects, settings=ON, diagnosis=None):
    imu, ref = render_replica(twin, seed, effects)
    fit = calibrate_session(imu, ref, twin.options)
    res = close_loop(imu, ref, twin.options, segments=fit.segments, diagnosis=diagnosis,
                     settings=settings)  # fmt: skip
    return imu, ref, fit, res


@pytest.fixture(scope="module")
def drift(twin):
    return _loop(twin, 11, (make_effect("temperature_drift"),))


def _resting_residuals(twin, imu, ref, calibration):
    """|a| - g (m/s^2) and |w| (rad/s) of the resting means (rate table left out), with the
    session's readings calibrated by ``calibration`` (its terms included)."""
    fit = calibrate_session(imu, ref, twin.options)
    acc, gyr = [], []
    for rec, rows in st.resting_rows(fit, None):
        if rec == "ratetable":
            continue
        table, _ = apply_calibration(imu[rec], {"units": SI_COLUMN_UNITS}, calibration, source=rec)
        acc.append(st.segment_means(table[list(ACC)].to_numpy(float), rows))
        gyr.append(st.segment_means(table[list(GYR)].to_numpy(float), rows))
    acc, gyr = np.vstack(acc), np.vstack(gyr)
    return np.linalg.norm(acc, axis=1) - twin.options.gravity_m_s2, np.linalg.norm(gyr, axis=1)


def test_temperature_recovers_the_simulated_drift_within_3_std(drift):
    _, _, _, res = drift
    poly = res["calibration"].terms.temperature
    true = make_effect("temperature_drift")
    gyr = poly["gyr"]
    assert len(gyr.bias) >= 1
    k_gyr, _ = true.coefficients("gyr")  # each axis its own coefficient, of either sign
    assert np.all(np.abs(gyr.bias[0] - k_gyr) < 3 * gyr.bias_std[0]), gyr.bias
    # resting poses see the accelerometer's bias and scale drift only together along gravity:
    # |a| moves by g s + b per kelvin for a pose along an axis (bias and scale are not
    # separable without poses along every axis at several temperatures); the poses away from
    # the cube's temperature (static recording, rotation rests) hold gravity near +z, so
    # that axis's is what the session shows
    acc = poly["acc"]
    g = 9.81
    got = g * (acc.scale[0] if len(acc.scale) else 0) + (acc.bias[0] if len(acc.bias) else 0)
    std = np.hypot(g * (acc.scale_std[0] if len(acc.scale) else 0),
                   acc.bias_std[0] if len(acc.bias) else 0)  # fmt: skip
    k_acc, s_acc = true.coefficients("acc")
    want = g * s_acc + k_acc
    assert abs(got[2] - want[2]) < 3 * std[2] + 1e-12, (got, want, std)


def test_temperature_term_improves_a_session_it_was_not_fitted_on(twin, drift):
    """The terms of session 11 calibrate session 12 of the same unit (same warm-up): the
    resting |a| - g and |w| shrink against the paper's calibration of session 11."""
    _, _, fit, res = drift
    imu, ref = render_replica(twin, 12, (make_effect("temperature_drift"),))
    a0, w0 = _resting_residuals(twin, imu, ref, fit.calibration)
    a1, w1 = _resting_residuals(twin, imu, ref, res["calibration"])
    rms = lambda x: float(np.sqrt(np.mean(x**2)))  # noqa: E731
    assert rms(a1) < 0.5 * rms(a0), (rms(a0), rms(a1))
    assert rms(w1) < 0.5 * rms(w0), (rms(w0), rms(w1))


def test_g_sensitivity_recovers_the_simulated_matrix_within_3_std(twin):
    effect = make_effect("g_sensitivity")
    _, _, _, res = _loop(twin, 11, (effect,))
    g = res["calibration"].terms.g_sensitivity
    true = np.asarray(effect.matrix)  # frame B, the term's parameterisation
    assert np.all(np.abs(g.matrix - true) < 3 * g.std), (g.matrix, true, g.std)


def test_mag_delay_recovers_the_mean_age_of_the_held_sample_within_3_std(twin):
    effect = make_effect("mag_latency", rate_hz=75.0, delay_s=0.05)
    imu, _, _, res = _loop(twin, 11, (effect,), TermSettings.only(mag_delay="on"))
    m = res["calibration"].terms.mag_delay
    # the truth is the mean age of the field values rotation3d carries (every 10th packet):
    # with the 75 Hz clock only two ages recur there, and their mean is the nominal
    # delay + 1 / (2 rate) only on average over the phase the recording drew
    session = simulate_session(twin.truth, 11, twin.config, (effect,), name="twin")
    phase = session.realised["mag_latency"]["rotation3d"]["phase_s"]
    rows = np.flatnonzero(np.all(np.isfinite(imu["rotation3d"][list(MAG)].to_numpy()), axis=1))
    t = rows / RATE_HZ
    age = float(np.mean(t - effect.held(t, phase)[1]))
    assert abs(m.delay_s - age) < 3 * m.std_s, (m.delay_s, age, m.std_s)


def test_temperature_refused_without_a_channel_and_below_the_span(twin, drift):
    _, _, _, res = _loop(
        twin,
        11,
        (),
        TermSettings.from_config({"temperature": "on", "g_sensitivity": "off", "mag_delay": "off"}),
    )
    assert res["calibration"] is None
    assert "no temperature channel" in res["terms"]["temperature"]["reason"]
    imu, ref, fit, _ = drift
    res = close_loop(imu, ref, twin.options, segments=fit.segments, diagnosis=None,
                     settings=TermSettings.from_config(
                         {"temperature": "on", "g_sensitivity": "off", "mag_delay": "off"},
                         temperature_min_span_c=8.0))  # fmt: skip
    assert res["calibration"] is None
    assert "below the 8 K" in res["terms"]["temperature"]["reason"]


def test_auto_on_a_clean_session_adds_nothing_and_is_byte_identical_to_off(twin, tmp_path):
    imu, ref = render_replica(twin, 11, ())
    fit = calibrate_session(imu, ref, twin.options)
    diagnosis = {
        "settings": {"min_heldout_shrink": 0.3},
        "effects": [{"name": "g_sensitivity", "accepted": False, "heldout_shrink": 0.05,
                     "note": ""}],
    }  # fmt: skip
    paper = calibration_of_what_ran(
        {s: {"calibration": fit.calibration.sensor(s).to_dict()} for s in SENSORS}
    )
    files = {}
    for name, settings in (
        ("auto", TermSettings.from_config()),
        ("off", TermSettings.only("off")),
    ):
        res = close_loop(imu, ref, twin.options, segments=fit.segments, diagnosis=diagnosis,
                         settings=settings)  # fmt: skip
        assert res["calibration"] is None
        path = tmp_path / f"{name}.json"
        path.write_text(json.dumps(final_calibration(paper, terms_summary(res))))
        files[name] = path.read_bytes()
    assert files["auto"] == files["off"]


def test_decide_follows_the_switch_and_the_diagnosis():
    diagnosis = {
        "settings": {"min_heldout_shrink": 0.3},
        "effects": [
            {"name": "temperature_drift", "accepted": True, "heldout_shrink": 0.8},
            {"name": "g_sensitivity", "accepted": False, "heldout_shrink": 0.1, "note": ""},
        ],
    }
    assert decide("temperature", TermSettings.from_config(), diagnosis) == (
        True, "auto: the diagnosis accepts temperature_drift, held-out shrink 0.80 "
        "(at least 0.3 needed)",
    )  # fmt: skip
    include, reason = decide("g_sensitivity", TermSettings.from_config(), diagnosis)
    assert not include and "does not accept g_sensitivity, held-out shrink 0.10" in reason
    assert decide("mag_delay", TermSettings.from_config(), diagnosis)[0] is False
    assert decide("temperature", TermSettings.from_config(temperature=False), diagnosis) == (
        False, "off in the config",
    )  # fmt: skip
    with pytest.raises(ValueError, match=r"terms\.temperature: 'sometimes' is not one of"):
        TermSettings.from_config(temperature="sometimes")


def test_settings_defaults_are_the_schemas():
    props = settings_schema()["properties"]
    defaults = TermSettings.from_config()
    assert TermSettings.from_config({k: v["default"] for k, v in props.items()}) == defaults
    assert defaults.to_config() == {k: v["default"] for k, v in props.items()}
    assert defaults.options["temperature"] == {"max_order": 3, "min_span_c": 2.0, "margin_c": 1.0}


def test_a_misspelt_terms_setting_is_named_with_the_closest_one():
    with pytest.raises(ValueError, match=r"'temperature_max_ordr' \(did you mean "
                       r"'temperature_max_order'\?\)"):  # fmt: skip
        TermSettings.from_config(temperature_max_ordr=2)
    with pytest.raises(ValueError, match=r"terms\.temperature_max_order: 0 is less than"):
        TermSettings.from_config(temperature_max_order=0)


def _with_temperature(calibration: ImuCalibration, margin_c: float = 1.0) -> ImuCalibration:
    poly = TemperaturePolynomial("gyr", 25.0, (22.0, 28.0), margin_c, [[1e-3, 2e-3, 3e-3]],
                                 [[1e-4, 0, 0]], [[1e-5] * 3], [[1e-5, 0, 0]])  # fmt: skip
    return calibration.with_terms(ModelTerms(temperature=TemperatureTerm({"gyr": poly})))


def _recording(n=50, temp=None):
    rng = np.random.default_rng(0)
    table = pd.DataFrame(rng.normal(size=(n, 9)), columns=[*ACC, *GYR, *MAG])
    table.insert(0, "t_s", np.arange(n) * 0.01)
    if temp is not None:
        table["temp_c"] = temp
    meta = {"units": SI_COLUMN_UNITS}
    return table, meta


def test_file_round_trip_and_format_1_still_read(drift):
    cal = drift[3]["calibration"]
    d = cal.to_dict()
    assert d["format_version"] == 2 and "terms" in d
    back = ImuCalibration.from_dict(json.loads(json.dumps(d)))
    assert back.to_dict() == d
    old = {k: v for k, v in d.items() if k != "terms"} | {"format_version": 1}
    assert ImuCalibration.from_dict(old).terms.empty


def test_apply_uses_the_temperature_term_and_warns_outside_its_range(drift, caplog):
    cal = _with_temperature(drift[2].calibration)
    table, meta = _recording(temp=np.full(50, 27.0))
    out, m = apply_calibration(table, meta, cal, source="rec.parquet")
    # at 27 deg C the gyro bias drift is 2 K * (1e-3, 2e-3, 3e-3), scale x (1 + 2e-4)
    g = cal.gyr
    raw = table[list(GYR)].to_numpy()
    want = (raw - g.bias - 2 * np.array([1e-3, 2e-3, 3e-3])) / (1 + np.array([2e-4, 0, 0]))
    np.testing.assert_allclose(out[list(GYR)].to_numpy(), want @ g.matrix.T, rtol=1e-12)
    assert m["model_terms"] == ["temperature"]
    assert m["temperature_outside_span"]["gyr"]["outside_fraction"] == 0
    table, meta = _recording()
    with pytest.raises(ValueError, match=r"rec\.parquet: .*no temperature column"):
        apply_calibration(table, meta, cal, source="rec.parquet")
    # beyond the margin (span up to 28 deg C, margin 1 K): corrected at 29 deg C, warned
    table, meta = _recording(temp=np.full(50, 30.5))
    with caplog.at_level("WARNING"):
        out, m = apply_calibration(table, meta, cal, source="rec.parquet")
    edge, _ = apply_calibration(*_recording(temp=np.full(50, 29.0)), cal, source="rec.parquet")
    np.testing.assert_allclose(out[list(GYR)].to_numpy(), edge[list(GYR)].to_numpy(), rtol=1e-12)
    assert m["temperature_outside_span"]["gyr"] == {
        "outside_fraction": 1.0, "max_outside_k": 2.5, "clamped_fraction": 1.0,
    }  # fmt: skip
    assert "rec.parquet: 100.0 % of the samples are outside the gyr calibration" in caplog.text
    assert "100.0 % beyond it corrected at the margin's edge" in caplog.text
    table, meta = _recording(temp=np.full(50, 28.5))
    _, m = apply_calibration(table, meta, cal, source="rec.parquet")
    assert m["temperature_outside_span"]["gyr"] == {
        "outside_fraction": 1.0, "max_outside_k": 0.5, "clamped_fraction": 0.0,
    }  # fmt: skip


def test_corrected_session_with_no_terms_is_the_session(twin, drift):
    imu, _, fit, _ = drift
    fixed = corrected_session({"cube": imu["cube"]}, fit.calibration, ModelTerms())
    np.testing.assert_allclose(fixed["cube"][list(ACC)], imu["cube"][list(ACC)], atol=1e-12)


def test_report_section_lists_the_terms_and_the_gap_before_and_after(drift, tmp_path):
    from imucal.report.lab import _environment
    from imucal.report.sections import terms_section

    (tmp_path / "terms.json").write_text(json.dumps(terms_summary(drift[3])))
    (tmp_path / "after.json").write_text(
        json.dumps({"gap": {"total": 1.5}, "remaining": {"total": 0.5}})
    )
    (tmp_path / "diagnosis.json").write_text(json.dumps({"gap": {"total": 40.0}}))
    ctx = terms_section(
        [tmp_path / "terms.json", tmp_path / "after.json"], [tmp_path / "diagnosis.json"]
    )
    html = _environment().get_template("_terms.html.j2").render(terms=ctx)
    assert "temperature gyr bias dT^1" in html
    # a warm-up alone: G is estimated (on) and refused by the held-out comparison
    assert "does not predict held-out resting segments better" in html
    assert "Gap before the terms (paper&#39;s model): 40" in html or "paper's model): 40" in html
    assert "gap 1.5" in html


def test_lever_arm_recovers_the_simulated_r_within_3_std(twin):
    effect = make_effect("lever_arm")
    _, _, _, res = _loop(twin, 11, (effect,), TermSettings.only(lever_arm="on"))
    r = res["calibration"].terms.lever_arm
    true = np.array([effect.x_m, effect.y_m, effect.z_m])
    assert np.all(np.abs(r.r_m - true) < 3 * r.std_m), (r.r_m, true, r.std_m)
    # the held-out run means (half the rate levels, predicted from the other half) lose the
    # centripetal term: what is left is the noise of a run mean
    held = res["terms"]["lever_arm"]["evidence"]["heldout_rms"]
    assert held["with"] < 0.05 * held["without"], held


def test_apply_takes_out_the_centripetal_acceleration_and_needs_the_gyroscope(drift):
    cal = drift[2].calibration
    r = np.array([0.03, 0.02, 0.01])
    with_arm = cal.with_terms(ModelTerms(lever_arm=LeverArm(r, np.full(3, 1e-4))))
    table, meta = _recording()
    # a constant raw rate: the tangential term is zero, the centripetal one w x (w x r)
    table[list(GYR)] = np.array([0.5, -1.0, 3.0])
    plain, _ = apply_calibration(table, meta, cal, source="rec.parquet")
    out, m = apply_calibration(table, meta, with_arm, source="rec.parquet")
    w = plain[list(GYR)].to_numpy()
    np.testing.assert_allclose(
        plain[list(ACC)].to_numpy() - out[list(ACC)].to_numpy(),
        np.cross(w, np.cross(w, r)),
        atol=1e-12,
    )
    assert m["model_terms"] == ["lever_arm"]
    table[list(GYR)] = np.nan
    with pytest.raises(ValueError, match=r"rec\.parquet: .*lever arm, which needs the gyroscope"):
        apply_calibration(table, meta, with_arm, source="rec.parquet")


def test_the_sessions_own_samples_are_inside_the_calibrated_span(drift):
    """The span is that of the samples the polynomials were fitted on (not of the segment
    means): the session's coldest and warmest samples are in its first and last rest."""
    imu, _, _, res = drift
    for name, table in imu.items():
        _, meta = apply_calibration(
            table, {"units": SI_COLUMN_UNITS}, res["calibration"], source=name
        )
        for sensor, flag in meta["temperature_outside_span"].items():
            assert flag["outside_fraction"] == 0, (name, sensor, flag)


@pytest.mark.slow  # a diagnosis with 8 replicas: about 35 s
def test_lever_arm_heldout_improvement_reaches_the_diagnosis_prediction(twin):
    from imucal.gap.diagnosis import diagnose
    from imucal.gap.scoring import DiagnosisSettings

    imu, ref = render_replica(twin, 11, (make_effect("lever_arm"),))
    diagnosis = diagnose(imu, ref, twin.options, dataset="lever_arm",
                         settings=DiagnosisSettings(replicas=8))  # fmt: skip
    fit = calibrate_session(imu, ref, twin.options)
    res = close_loop(imu, ref, twin.options, segments=fit.segments, diagnosis=diagnosis,
                     settings=TermSettings.only(lever_arm="auto"))  # fmt: skip
    r = res["terms"]["lever_arm"]
    assert r["included"], r["reason"]
    h = r["heldout"]
    # the achieved shrink of the mean square is a lower bound of that of the excess the
    # diagnosis's shrink measures: the term must not fall short of it by 3 of its std
    assert h["predicted_shrink"] is not None and not h["short_of_prediction"], h
    assert h["achieved_shrink"] + 3 * h["achieved_std"] >= h["predicted_shrink"], h


def test_heldout_comparison_is_one_sided_against_the_prediction():
    from imucal.terms.heldout import heldout_comparison

    evidence = {"heldout_rms": {"without": 1.0, "with": 0.5, "values": 16}}
    # achieved 1 - 0.25 = 0.75, std 0.25 * sqrt(4 / 16) = 0.125
    for predicted, short in ((0.5, False), (0.95, False), (1.2, True)):
        diagnosis = {"effects": [{"name": "lever_arm", "heldout_shrink": predicted}]}
        h = heldout_comparison("lever_arm", evidence, diagnosis)
        assert h["achieved_shrink"] == pytest.approx(0.75)
        assert h["achieved_std"] == pytest.approx(0.125)
        assert h["short_of_prediction"] is short
    assert heldout_comparison("lever_arm", evidence, None)["short_of_prediction"] is None
    assert "note" in heldout_comparison("mag_delay", {}, None)


def test_pose_to_pose_gravity_held_out_improves_with_the_terms(drift):
    """The platform's turns are used by no term's estimator: the up direction of each
    rotation3d rest predicted from the previous one through the integrated gyro comes closer
    to the measured one with the temperature term (the drift turns the integral)."""
    _, _, _, res = drift
    p2p = res["pose_to_pose"]
    assert p2p["values"] >= 2
    assert p2p["rms_with"] < 0.2 * p2p["rms_without"], p2p


def test_gap_comparison_is_two_sided():
    from imucal.terms.comparison import gap_comparison

    before = {"gap": {"total": 5000.0, "null_p95": 30.0},
              "remaining": {"total": 150.0, "significant": True},
              "explained": ["temperature_drift", "bias_instability"]}  # fmt: skip

    def after(remaining, explained=("bias_instability",), significant=True):
        return {"gap": {"total": remaining + 100, "null_p95": 40.0},
                "remaining": {"total": remaining, "significant": significant},
                "explained": list(explained)}  # fmt: skip

    verdicts = {r: gap_comparison(before, after(r), ["temperature"])["verdict"]
                for r in (60.0, 180.0, 400.0)}  # fmt: skip
    assert verdicts == {60.0: "better than predicted", 180.0: "as predicted",
                        400.0: "short of the prediction"}  # fmt: skip
    # the diagnoses' own significance decides when one side has no gap left
    closed = after(16.0, significant=False)
    assert gap_comparison(before, closed, ["temperature"])["verdict"] == "better than predicted"
    none_left = {**before, "remaining": {"total": 0.0, "significant": False}}
    assert gap_comparison(none_left, closed, ["temperature"])["verdict"].startswith("as predicted")
    assert gap_comparison(none_left, after(60.0), ["temperature"])["verdict"] == (
        "short of the prediction"
    )
    # the term's effect explained again after: the term did not take it
    verdict = gap_comparison(before, after(100.0, ["temperature_drift"]), ["temperature"])
    assert verdict["verdict"].startswith("short of the prediction: the diagnosis after still")
    assert gap_comparison(before, {"note": "no model term"}, []) is None


#: Sessions where a drift with temperature and a g-sensitivity compete for the same resting
#: gyro means: each effect at its realistic default (a per-axis, mixed-sign warm-up drift of a
#: real part's shape; a full 3x3 G), alone and together.
COMPETING = {
    "warm-up": ("temperature_drift",),
    "g-sensitivity": ("g_sensitivity",),
    "both": ("temperature_drift", "g_sensitivity"),
}


@pytest.mark.slow  # a diagnosis with 8 replicas and the closed loop: about 50 s per case
@pytest.mark.parametrize("case", list(COMPETING))
def test_competing_explanations_get_the_right_terms_with_their_coefficients(twin, case):
    """The diagnosis names exactly the simulated effects among the two, and the closed loop
    on ``auto`` writes exactly their terms; each term recovers the simulated coefficients
    within 3 of its reported standard deviations (the gyro drift per axis; the accelerometer
    along +z, the axis the poses away from the cube's temperature see; every entry of G)."""
    from imucal.gap.diagnosis import diagnose
    from imucal.gap.scoring import DiagnosisSettings

    effects = tuple(make_effect(name) for name in COMPETING[case])
    imu, ref = render_replica(twin, 21, effects)
    diagnosis = diagnose(imu, ref, twin.options, dataset=case,
                         settings=DiagnosisSettings(replicas=8))  # fmt: skip
    named = {"temperature_drift", "g_sensitivity"} & set(diagnosis["explained"])
    assert named == set(COMPETING[case]), (diagnosis["explained"], diagnosis["confusable"])
    fit = calibrate_session(imu, ref, twin.options)
    res = close_loop(imu, ref, twin.options, segments=fit.segments, diagnosis=diagnosis,
                     settings=TermSettings.only(temperature="auto", g_sensitivity="auto"))  # fmt: skip
    terms = res["calibration"].terms
    want = {"temperature": "temperature_drift" in COMPETING[case],
            "g_sensitivity": "g_sensitivity" in COMPETING[case]}  # fmt: skip
    for term, included in want.items():
        assert res["terms"][term]["included"] == included, (term, res["terms"][term]["reason"])
    if want["temperature"]:
        true = next(e for e in effects if e.name == "temperature_drift")
        gyr = terms.temperature["gyr"]
        k_gyr, _ = true.coefficients("gyr")
        assert np.all(np.abs(gyr.bias[0] - k_gyr) < 3 * gyr.bias_std[0]), (gyr.bias, k_gyr)
        acc = terms.temperature["acc"]
        k_acc, s_acc = true.coefficients("acc")
        got = 9.81 * (acc.scale[0] if len(acc.scale) else 0) + (acc.bias[0] if len(acc.bias) else 0)
        std = np.hypot(9.81 * (acc.scale_std[0] if len(acc.scale) else 0),
                       acc.bias_std[0] if len(acc.bias) else 0)  # fmt: skip
        assert abs(got[2] - (9.81 * s_acc[2] + k_acc[2])) < 3 * std[2], (got, std)
    if want["g_sensitivity"]:
        true = np.asarray(next(e for e in effects if e.name == "g_sensitivity").matrix)
        g = terms.g_sensitivity
        assert np.all(np.abs(g.matrix - true) < 3 * g.std), (g.matrix, true, g.std)


@pytest.mark.slow
def test_term_std_follows_the_errors_over_sessions(twin, rms_z_band):
    """8 sessions of the twin with a g-sensitivity, a lever arm and a temperature drift: the
    g-sensitivity matrix (9 entries), the lever arm (3) and the gyroscope's bias drift per
    kelvin (3) against the truth, each term's z pooled (72, 24 and 24 draws; one session's
    are not all independent). Each RMS z within the 1 - 1e-4 interval of that many standard
    normal draws over the three terms (0.67-1.36 for 72, 0.46-1.63 for 24); seen 0.95, 1.36
    and 0.72."""
    effects = tuple(make_effect(e) for e in ("g_sensitivity", "lever_arm", "temperature_drift"))
    g_effect, lever, drift = effects
    true_g = np.asarray(g_effect.matrix)
    true_r = np.array([lever.x_m, lever.y_m, lever.z_m])
    z = {"g_sensitivity": [], "lever_arm": [], "temperature": []}
    for seed in range(20, 28):
        terms = _loop(twin, seed, effects, TermSettings.only("on", mag_delay="off"))[3]
        terms = terms["calibration"].terms
        z["g_sensitivity"].append(
            ((terms.g_sensitivity.matrix - true_g) / terms.g_sensitivity.std).ravel()
        )
        z["lever_arm"].append((terms.lever_arm.r_m - true_r) / terms.lever_arm.std_m)
        gyr = terms.temperature["gyr"]
        z["temperature"].append((gyr.bias[0] - drift.coefficients("gyr")[0]) / gyr.bias_std[0])
    failed = []
    for name, values in z.items():
        values = np.ravel(values)
        low, high = rms_z_band(values.size, 1e-4 / len(z))
        rms = float(np.sqrt(np.mean(values**2)))
        if not low < rms < high:
            failed.append(f"{name}: RMS z {rms:.2f} of {values.size}, [{low:.2f}, {high:.2f}]")
    assert not failed, failed


def _count_stage_runs(monkeypatch) -> list[set]:
    """The stages each call of the in-process runner runs, in call order."""
    from imucal.pipeline import full

    runs = []
    run_nodes = full.run_nodes

    def counted(store, options, *, nodes):
        runs.append(set(nodes))
        return run_nodes(store, options, nodes=nodes)

    monkeypatch.setattr(full, "run_nodes", counted)
    return runs


def test_the_loop_estimates_on_the_sessions_own_stage_files(twin, drift, tmp_path, monkeypatch):
    # the workflow hands the loop the stage rules' JSON files: the loop then runs none of the
    # chain's stages for its base fit, and ships what a second run of the chain gives
    from imucal.io import read_json, write_json

    imu, ref, fit, res = drift
    files = {}
    for name, record in fit.extra["records"].items():
        write_json(record, tmp_path / f"{name}.json")
        files[name] = read_json(tmp_path / f"{name}.json")
    runs = _count_stage_runs(monkeypatch)
    again = close_loop(imu, ref, twin.options, segments=fit.segments, diagnosis=None,
                       settings=ON, fits=files)  # fmt: skip
    assert runs[0] == set()  # the base fit: every stage from its file
    assert len(runs) > 1  # the refit of the corrected session runs the chain
    assert again["calibration"].to_dict() == res["calibration"].to_dict()


def test_the_refit_runs_only_the_stages_whose_readings_the_terms_change(twin, drift, monkeypatch):
    # a gyroscope-only term leaves the accelerometer's and magnetometer's readings to the bit:
    # their stages are taken from the session's fit, and the result is the whole chain's
    from imucal.modelterms import GSensitivity
    from imucal.terms.loop import changed_sensors, recalibrate

    imu, ref, fit, _ = drift
    g = GSensitivity(np.diag([2e-4, -1e-4, 3e-4]), np.full((3, 3), 1e-5))
    corrected = corrected_session(imu, fit.calibration, ModelTerms(g_sensitivity=g))
    assert changed_sensors(imu, corrected) == {"gyr"}
    runs = _count_stage_runs(monkeypatch)
    refit = recalibrate(fit, corrected, twin.options)
    assert runs[0] == {"gyr_bias", "gyr_align", "gyr_scale", "gyr_table", "gyr_table_align", "gyr"}
    whole = calibrate_session(corrected, ref, twin.options, fit.segments)
    assert refit.calibration.to_dict() == whole.calibration.to_dict()
