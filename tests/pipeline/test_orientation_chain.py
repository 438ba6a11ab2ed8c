"""The orientation reference in the chain: stage gyr_reference of a partial session and the
validation of its calibration against held-out and fitted recordings (simulated sessions)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from conftest import partial_session, si_options, z_limit
from scipy.spatial.transform import Rotation

from imucal import errormodel
from imucal.calibration import SensorCalibration
from imucal.columns import ACC, GYR, MAG, QUAT, SEGMENT_COLUMNS, TIME
from imucal.pipeline import partial
from imucal.pipeline.reference import validate_references
from imucal.sim.orientation import simulate_orientation_session

MATRIX = errormodel.compose([1.03, 0.98, 1.01], [0.005, -0.004, 0.006], [0.0, 0.0, 0.0])
BIAS = np.array([0.015, -0.01, 0.02])
MOUNTING = Rotation.from_rotvec([0.2, 0.4, -0.9]).as_matrix()
ACC_MATRIX = errormodel.compose([1.02, 0.99, 0.98], [0.003, 0.002, -0.004], [0.01, -0.02, 0.015])
ACC_BIAS = np.array([0.1, -0.05, 0.2])
#: The magnetometer's soft iron, non-orthogonality and misalignment to the gyroscope's axes.
MAG_MATRIX = errormodel.compose([1.1, 0.9, 1.05], [0.02, -0.03, 0.01], [0.05, -0.04, 0.1])
MAG_BIAS = np.array([0.3, -0.2, 0.4])


def as_tables(session, name):
    table = pd.DataFrame({TIME: session.t_module, **dict(zip(ACC, session.acc.T)),
                          **dict(zip(GYR, session.gyr.T)), **dict(zip(MAG, session.mag.T))})  # fmt: skip
    reference = pd.DataFrame(
        {TIME: session.t_reference, **dict(zip(QUAT, session.quat_reference.T))}
    )
    rests = []
    for k, (lo, hi) in enumerate(session.rests_s):
        i0, i1 = np.searchsorted(session.t_module, [lo, hi])
        rests.append({"recording": name, "label": f"s{k + 1:02d}", "kind": "static",
                      "start_s": lo, "end_s": hi, "start_index": i0, "end_index": i1, "axis": "",
                      "rate_dps": np.nan, "sense": 0, "turns": np.nan, "up": "",
                      "angle_deg": np.nan})  # fmt: skip
    return table, reference, pd.DataFrame(rests, columns=list(SEGMENT_COLUMNS))


@pytest.fixture(scope="module")
def chain():
    fit = simulate_orientation_session(21, matrix=MATRIX, bias=BIAS, mounting=MOUNTING,
                                       offset_s=0.8, drift_ppm=30.0, duration_s=240.0,
                                       acc_matrix=ACC_MATRIX, acc_bias=ACC_BIAS,
                                       acc_noise_m_s2=0.02, mag_matrix=MAG_MATRIX,
                                       mag_bias=MAG_BIAS)  # fmt: skip
    held = simulate_orientation_session(22, matrix=MATRIX, bias=BIAS, mounting=MOUNTING,
                                        offset_s=-0.4, reference_rate_hz=100.0,
                                        mag_matrix=MAG_MATRIX, mag_bias=MAG_BIAS)  # fmt: skip
    t_fit, r_fit, s_fit = as_tables(fit, "tumble")
    t_held, r_held, s_held = as_tables(held, "poses")
    tables = {"tumble": t_fit, "poses": t_held}
    references = {"tumble": (r_fit, {"held_out": False, "up": "+z"}),
                  "poses": (r_held, {"held_out": True, "up": "+z"})}  # fmt: skip
    segments = pd.concat([s_fit, s_held], ignore_index=True)
    where = {n: f"recordings.{n}.reference" for n in tables}
    outcomes = partial.run_stages(
        partial_session(tables, segments, references=references, reference_where=where)
    )
    return tables, references, segments, outcomes


def test_gyr_reference_calibrates_the_gyroscope_of_a_partial_session(chain):
    _, _, _, outcomes = chain
    done = {o.name: o for o in outcomes}
    assert done["gyr_reference"].status == "run", done["gyr_reference"].reason
    artifact = done["gyr_reference"].artifact
    assert artifact["recordings"] == ["tumble"]  # the held-out one is not fitted on
    # the fitted matrix does better than the nominal one on its own data and the held-out
    assert "fallback" not in artifact and "warnings" not in artifact
    checks = artifact["checks"]
    assert checks["own data"]["worse"] is False and checks["held-out data"]["worse"] is False
    final = partial.final_calibration(outcomes, si_options())
    assert final["sensors"]["gyr"]["stage"] == "gyr_reference"
    matrix = np.array(final["sensors"]["gyr"]["calibration"]["matrix"])
    assert np.abs(matrix - MATRIX).max() < 2e-3
    offset = artifact["alignments"]["tumble"]["time"]
    truth_mid = 0.8 + 30e-6 * offset["t_mid_s"]
    assert abs(offset["offset_mid_s"] - truth_mid) < 1 / 120.0


def test_held_out_validation_raw_bias_calibrated(chain):
    tables, references, segments, outcomes = chain
    final = partial.final_calibration(outcomes, si_options())
    calibration = {s: e["calibration"] for s, e in final["sensors"].items()}
    bias = next(o for o in outcomes if o.name == "gyr_bias").artifact["bias_ls_rad_s"]
    result = validate_references(tables, references, segments, calibration, bias,
                                 {n: n for n in tables}, windows_s=(1.0, 10.0))  # fmt: skip
    held = result["summary"]["poses"]
    assert held["held_out"] and held["reference_period_ms"] == pytest.approx(10.0)
    assert abs(held["offset_ms"] + 400.0) < 10.0  # within one reference sample
    ten = held["orientation_median_deg_10s"]
    # the scale errors (3 %) of the bias-only gyroscope turn 2 rad/s into ~0.06 rad/s: degrees
    # in 10 s. Calibrated, noise remains: the random walk 0.01 rad/s sqrt(10 s / 200 Hz) =
    # 0.13 deg and the reference's sqrt(2) 0.0005 rad = 0.04 deg per axis, whose 3-D norm has
    # a median of 1.54 sigma = 0.21 deg; twice that bounds it
    assert ten["raw"] > ten["bias"] > 1.0 > 0.42 > ten["calibrated"]
    record = result["recordings"]["poses"]
    assert record["calibrated"]["rates"]["x"]["slope"] == pytest.approx(1.0, abs=2e-3)
    assert record["gravity"]["raw"]["n"] == len(segments.query("recording == 'poses'"))
    # the calibration carries over: the paired test says so and warns of nothing
    assert record["transfer"]["windows"]["10s"]["verdict"] == "better"
    assert record["transfer"]["warnings"] == []
    assert held["transfer"] == {"1s": "better", "10s": "better"}
    assert "transfer" not in result["recordings"]["tumble"]  # fitted on: no held-out test


def test_mag_reference_aligns_the_magnetometer_to_the_gyroscope(chain):
    _, _, _, outcomes = chain
    done = {o.name: o for o in outcomes}
    assert done["mag_step2"].status == "skipped"  # no rotation3d phases
    assert done["mag_reference"].status == "run", done["mag_reference"].reason
    final = partial.final_calibration(outcomes, si_options())["sensors"]["mag"]
    assert final["stage"] == "mag_reference"
    cal = SensorCalibration.from_dict("mag", final["calibration"])
    np.testing.assert_allclose(cal.bias, MAG_BIAS, atol=2e-3)
    np.testing.assert_allclose(cal.matrix, MAG_MATRIX, atol=2e-3)
    # and the reported uncertainty covers the error: the jackknife's 10 blocks give its std 9
    # dof, so Student's t(9), two-sided over the 9 entries at 1e-4
    std = np.asarray(cal.std["matrix"])
    assert np.all(np.abs(cal.matrix - MAG_MATRIX) < z_limit(9, dof=9) * std + 1e-4)


def test_field_direction_as_read_and_calibrated(chain):
    tables, references, segments, outcomes = chain
    final = partial.final_calibration(outcomes, si_options())
    calibration = {s: e["calibration"] for s, e in final["sensors"].items()}
    result = validate_references(tables, references, segments, calibration, None,
                                 {n: n for n in tables}, windows_s=(10.0,))  # fmt: skip
    field = result["recordings"]["poses"]["field"]
    # as read, the hard iron (|b| ~ 0.54 of the field) turns with the body: tens of degrees;
    # calibrated on the other recording, the alignment's error remains (about 0.1 deg)
    assert field["calibrated"]["median_deg"] < 0.3 < 10.0 < field["raw"]["median_deg"]
    assert "warnings" not in field
    # a calibration that makes it worse is said to
    wrong = SensorCalibration("mag", -MAG_BIAS, MAG_MATRIX, "normalised").to_dict()
    worse = validate_references(tables, references, segments, calibration | {"mag": wrong},
                                None, {n: n for n in tables}, windows_s=(10.0,))  # fmt: skip
    assert "scatters more" in worse["recordings"]["poses"]["field"]["warnings"][0]


def test_every_reference_held_out_skips_the_stage(chain):
    tables, references, segments, _ = chain
    held = {n: (r, {**m, "held_out": True}) for n, (r, m) in references.items()}
    outcomes = partial.run_stages(partial_session(tables, segments, references=held))
    stage = next(o for o in outcomes if o.name == "gyr_reference")
    assert stage.status == "skipped" and "is held_out; expected one to fit on" in stage.reason
    # nor do they feed any other fit: no gyroscope bias from their rests either
    final = partial.final_calibration(outcomes, si_options())
    assert final["sensors"] == {} and set(final["missing"]) == {"acc", "gyr", "mag"}


def test_a_held_out_recording_enters_no_fit(chain):
    # the fixture holds 'poses' out: neither the ellipsoid, nor the cube fit, nor the gyroscope
    # bias (which took every recording's rests before) may see it
    tables, references, segments, outcomes = chain
    done = {o.name: o for o in outcomes}
    assert done["mag_step1"].artifact["source"] == "tumble"
    assert "poses" not in done["mag_step1"].artifact["offered"]
    assert done["acc_cube"].status == "skipped" or done["acc_cube"].artifact["recording"] != "poses"
    assert done["gyr_reference"].artifact["held_out"] == ["poses"]
    # the same session with 'poses' fitted too: the gyroscope bias changes (more rests)
    both = {n: (r, {**m, "held_out": False}) for n, (r, m) in references.items()}
    bias_held = done["gyr_bias"].artifact["bias_ls_rad_s"]
    again = partial.run_stages(partial_session(tables, segments, references=both))
    bias_both = next(o for o in again if o.name == "gyr_bias").artifact["bias_ls_rad_s"]
    assert bias_held != bias_both


def test_acc_reference_in_the_gyroscope_frame(chain):
    _, _, _, outcomes = chain
    done = {o.name: o for o in outcomes}
    assert done["acc_reference"].status == "run", done["acc_reference"].reason
    final = partial.final_calibration(outcomes, si_options())
    assert final["sensors"]["acc"]["stage"] == "acc_reference"
    cal = final["sensors"]["acc"]["calibration"]
    matrix, bias = np.array(cal["matrix"]), np.array(cal["bias"])
    std_m, std_b = np.array(cal["std"]["matrix"]), np.array(cal["std"]["bias"])
    # B of the accelerometer is the gyroscope's B (the truth's), within the stated uncertainty:
    # 12 rests of 2.4 s, noise 0.02 m/s^2 and the reference's tilt noise 0.0005 rad
    z = z_limit(12)  # two-sided over the 12 entries at 1e-4
    assert np.all(np.abs(matrix - ACC_MATRIX) < z * std_m + 1e-4)
    assert np.all(np.abs(bias - ACC_BIAS) < z * std_b + 1e-4)
    assert np.abs(matrix - ACC_MATRIX).max() < 5e-3


def test_fit_worse_than_its_fallback_on_held_out_data_is_not_shipped():
    from imucal.pipeline.reference import fit_gyr_reference

    # fitted where the gyroscope reads 3 % low, held out where it reads right (a scale that
    # does not carry over): on the held-out recording the nominal matrix does better
    fit = simulate_orientation_session(31, matrix=MATRIX, bias=BIAS, mounting=MOUNTING,
                                       duration_s=100.0)  # fmt: skip
    held = simulate_orientation_session(32, matrix=np.eye(3), bias=BIAS, mounting=MOUNTING,
                                        duration_s=100.0)  # fmt: skip
    t_fit, r_fit, _ = as_tables(fit, "tumble")
    t_held, r_held, _ = as_tables(held, "poses")
    references = {"tumble": (r_fit, {"held_out": False}), "poses": (r_held, {"held_out": True})}
    out = fit_gyr_reference({"tumble": t_fit, "poses": t_held}, references, None,
                            {"tumble": "tumble", "poses": "poses"})  # fmt: skip
    assert out["checks"]["own data"]["worse"] is False
    assert out["checks"]["held-out data"]["worse"] is True
    np.testing.assert_array_equal(out["calibration"]["matrix"], np.eye(3))
    assert (
        np.abs(np.array(out["fallback"]["fitted"]["calibration"]["matrix"]) - MATRIX).max() < 2e-3
    )
    assert "on held-out data (poses)" in out["fallback"]["reason"]
    assert out["warnings"][0].startswith(
        "gyr_reference: the fitted matrix is not shipped, the "
        "nominal matrix with the bias fitted against the reference is"
    )
