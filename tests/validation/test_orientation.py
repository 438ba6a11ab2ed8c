"""Orientation reference: time alignment and mounting from the gyroscope, and the agreement
metrics, on simulated sessions (reference at another rate, offset, drift, mounting, gaps)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import z_limit
from scipy.spatial.transform import Rotation

from imucal import errormodel
from imucal.orientation import body_rates, integrate_rates, quat_conjugate
from imucal.sim.orientation import FIELD_DIP_DEG, simulate_orientation_session
from imucal.validation.orientation import (
    align_orientation_reference,
    compare_window_errors,
    field_direction_errors,
    gravity_errors,
    orientation_errors,
    rate_agreement,
    window_errors,
)

MATRIX = errormodel.compose([1.02, 0.97, 1.01], [0.004, -0.006, 0.003], [0.0, 0.0, 0.0])
BIAS = np.array([0.01, -0.02, 0.005])
MOUNTING = Rotation.from_rotvec([0.3, -0.5, 1.2]).as_matrix()


def angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.degrees(np.linalg.norm(Rotation.from_matrix(a @ b.T).as_rotvec())))


@pytest.fixture(scope="module")
def session():
    return simulate_orientation_session(
        3, matrix=MATRIX, bias=BIAS, mounting=MOUNTING, offset_s=3.217, drift_ppm=40.0
    )


def test_body_rates_never_span_a_gap():
    t = np.arange(10) * 0.01
    w = np.tile([0.0, 0.0, 1.0], (10, 1))
    q = integrate_rates(t, w)
    q[4] = np.nan
    start, end, rate = body_rates(t, q)
    # intervals 3-4 and 4-5 touch the gap; the other seven are exact
    assert start.size == 7 and not np.any((start <= 0.04) & (end >= 0.04))
    np.testing.assert_allclose(rate, np.tile([0.0, 0.0, 1.0], (7, 1)), atol=1e-12)
    start, _, _ = body_rates(t, q, step=2)
    assert start.size == 5


def test_offset_within_a_reference_sample_and_mounting_within_0_1_deg(session):
    s = session
    calibrated = errormodel.apply(MATRIX, BIAS, s.gyr)  # frame B exactly: the mounting is M
    al = align_orientation_reference(s.t_module, calibrated, s.t_reference, s.quat_reference)
    period = 1.0 / 120.0
    assert al.reference_period_s == pytest.approx(period)
    assert abs(al.time.offset_mid_s - (s.offset_s + s.drift_ppm * 1e-6 * al.time.t_mid_s)) < period
    # and within its stated uncertainty: Student's t with the 4 dof of the Birge ratio from
    # 6 windows, two-sided, 1e-4 over offset and drift
    z = z_limit(2, dof=4)
    truth_mid = s.offset_s + s.drift_ppm * 1e-6 * al.time.t_mid_s
    assert abs(al.time.offset_mid_s - truth_mid) < z * al.time.offset_mid_std_s + 1e-4
    # the drift (40 ppm over 120 s: 4.8 ms, half a reference sample) is resolved
    assert abs(al.time.drift_ppm - s.drift_ppm) < z * al.time.drift_std_ppm
    error = angle_deg(al.mounting.matrix, MOUNTING)
    assert error < 0.1
    assert error < 4 * al.mounting.angle_std_deg
    assert al.explained > 0.99


def test_bad_declarations_name_the_key(session):
    s = session
    calibrated = errormodel.apply(MATRIX, BIAS, s.gyr)
    scalar_last = s.quat_reference[:, [1, 2, 3, 0]]  # w, x, y, z read as x, y, z, w
    with pytest.raises(ValueError, match=r"recordings.poses.reference: .* check .*scalar"):
        align_orientation_reference(s.t_module, calibrated, s.t_reference, scalar_last,
                                    where="d.yaml: recordings.poses.reference")  # fmt: skip
    with pytest.raises(
        ValueError,
        match=r"recordings.poses.reference: the mounted .* check "
        r"recordings.poses.reference.rotates",
    ):
        align_orientation_reference(s.t_module, calibrated, s.t_reference,
                                    quat_conjugate(s.quat_reference),
                                    where="d.yaml: recordings.poses.reference")  # fmt: skip
    other = simulate_orientation_session(11, matrix=MATRIX, bias=BIAS, mounting=MOUNTING)
    with pytest.raises(
        ValueError,
        match=r"recordings.poses.reference: the reference's "
        r"\|omega\|\^2 correlates .* recorded with this recording",
    ):
        align_orientation_reference(s.t_module, calibrated, other.t_reference,
                                    other.quat_reference,
                                    where="d.yaml: recordings.poses.reference")  # fmt: skip


def test_metrics_calibrated_against_raw(session):
    s = session
    calibrated = errormodel.apply(MATRIX, BIAS, s.gyr)
    al = align_orientation_reference(s.t_module, calibrated, s.t_reference, s.quat_reference)
    rates = rate_agreement(s.t_module, calibrated, s.t_reference, s.quat_reference, al, MOUNTING)
    # the rate error is the reference's finite-difference noise: sqrt(2) sigma_q / dt per axis
    expected = np.sqrt(2) * 0.0005 * 120.0
    for axis in "xyz":
        assert rates[axis]["rms_rad_s"] == pytest.approx(expected, rel=0.15)
        assert abs(rates[axis]["slope"] - 1) < 5e-3
    raw = orientation_errors(s.t_module, s.gyr, s.t_reference, s.quat_reference, al, MOUNTING,
                             windows_s=(10.0,))["10s"]  # fmt: skip
    cal = orientation_errors(s.t_module, calibrated, s.t_reference, s.quat_reference, al,
                             MOUNTING, windows_s=(10.0,))["10s"]  # fmt: skip
    # the bias alone (~0.023 rad/s) turns raw by ~13 deg in 10 s; calibrated, noise only: the
    # random walk 0.01 rad/s sqrt(10 s / 200 Hz) = 0.13 deg and the reference's
    # sqrt(2) 0.0005 rad = 0.04 deg per axis, whose 3-D norm has a median of 1.54 sigma =
    # 0.21 deg; twice that bounds it
    assert raw["median_deg"] > 5.0
    assert cal["median_deg"] < 0.42
    assert cal["n"] > 80
    grav = gravity_errors(
        s.t_module, s.acc, s.rests_s, s.t_reference, s.quat_reference, al, MOUNTING, "+z"
    )
    assert grav["n"] == len(s.rests_s)
    assert grav["max_deg"] < 0.05  # the reference noise averaged over a rest


def test_field_direction_constant_only_once_calibrated():
    mag_matrix = errormodel.compose([1.1, 0.9, 1.05], [0.02, -0.03, 0.01], [0.0, 0.0, 0.0])
    mag_bias = np.array([0.3, -0.2, 0.4])  # hard iron of the order of the field
    s = simulate_orientation_session(
        3, matrix=MATRIX, bias=BIAS, mounting=MOUNTING, mag_matrix=mag_matrix, mag_bias=mag_bias
    )
    calibrated = errormodel.apply(MATRIX, BIAS, s.gyr)
    al = align_orientation_reference(s.t_module, calibrated, s.t_reference, s.quat_reference)
    mag_b = errormodel.apply(mag_matrix, mag_bias, s.mag)
    cal = field_direction_errors(s.t_module, mag_b, s.t_reference, s.quat_reference, al,
                                 MOUNTING, "+z")  # fmt: skip
    raw = field_direction_errors(s.t_module, s.mag, s.t_reference, s.quat_reference, al,
                                 MOUNTING, "+z")  # fmt: skip
    # calibrated: the reference's orientation noise (0.0005 rad per axis, a 2-D angle of
    # median 1.18 sigma = 0.034 deg) and the mounting's error (< 0.1 deg) remain
    assert cal["median_deg"] < 0.1
    assert cal["dip_deg"] == pytest.approx(FIELD_DIP_DEG, abs=0.1)
    assert cal["n"] > 0.9 * np.count_nonzero(np.all(np.isfinite(s.quat_reference), axis=1))
    # as read, the hard iron (|b| ~ 0.54 of the field) turns with the body: tens of degrees
    assert raw["median_deg"] > 10.0


def test_window_comparison_finds_the_worse_gyroscope(session):
    s = session
    calibrated = errormodel.apply(MATRIX, BIAS, s.gyr)
    al = align_orientation_reference(s.t_module, calibrated, s.t_reference, s.quat_reference)
    # a scale error of 1 % on every axis: ~2 rad/s x 10 s x 1 % = 11 deg per 10 s window
    scaled = 1.01 * calibrated
    good = window_errors(s.t_module, calibrated, s.t_reference, s.quat_reference, al,
                         MOUNTING, (10.0,))["10s"]  # fmt: skip
    bad = window_errors(s.t_module, scaled, s.t_reference, s.quat_reference, al,
                        MOUNTING, (10.0,))["10s"]  # fmt: skip
    worse = compare_window_errors(bad, good, 10.0)
    assert worse["verdict"] == "worse" and worse["median_difference_deg"] > 0
    assert compare_window_errors(good, bad, 10.0)["verdict"] == "better"
    # only independent windows enter: 120 s holds at most 12 of 10 s
    assert 6 <= worse["n_windows"] <= 12
    # two gyroscopes equal but for their own white noise of the same level: no difference
    rng = np.random.default_rng(1)
    one, two = (
        window_errors(s.t_module, calibrated + rng.normal(0, 0.01, calibrated.shape),
                      s.t_reference, s.quat_reference, al, MOUNTING, (10.0,))["10s"]
        for _ in range(2)
    )  # fmt: skip
    assert compare_window_errors(one, two, 10.0)["verdict"] == "no significant difference"
    few = compare_window_errors(bad, good, 30.0)
    assert few["verdict"] == "too few windows" and few["p_value"] is None
