"""The shipped standard deviations checked on independent parts: the arithmetic (whitening,
per-parameter z, inflation, the cuts), the decision on made-up part fits, and the verdict on
simulated sessions (white noise: RMS z in its chi-square band; model errors: inflated or warned).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from imucal import uncertainty
from imucal.calibration import SensorCalibration
from imucal.columns import ACC, GYR, TIME
from imucal.segments.table import segment_row, segments_frame
from imucal.validation.consistency import (
    HELDOUT_RATIO,
    RMS_Z_LIMIT,
    SIGNIFICANT_P,
    PartFit,
    check_parts,
    compare_parts,
    group_rms_z,
    inflate,
    sensor_covariance,
    ship,
)
from imucal.validation.parts import split_session


def _random_covariance(rng: np.random.Generator, n: int) -> np.ndarray:
    a = rng.normal(size=(n, n))
    return a @ a.T + 0.1 * np.eye(n)


def test_group_rms_z_whitens_with_the_full_covariance():
    rng = np.random.default_rng(0)
    covariance = _random_covariance(rng, 3)
    z = np.array([1.0, -2.0, 0.5])
    difference = np.linalg.cholesky(covariance) @ z
    rms, rank = group_rms_z(difference, covariance)
    assert rank == 3
    assert rms == pytest.approx(np.sqrt(z @ z / 3), rel=1e-10)
    # the diagonal alone (a dropped correlation) gives another number
    diagonal = np.sqrt(np.mean(difference**2 / np.diag(covariance)))
    assert abs(diagonal - rms) > 0.05


def test_group_rms_z_counts_only_the_directions_the_covariance_constrains():
    covariance = np.diag([4.0, 1.0, 0.0])  # the third parameter is fixed (no std)
    rms, rank = group_rms_z(np.array([2.0, -1.0, 0.0]), covariance)
    assert rank == 2 and rms == pytest.approx(1.0)
    assert group_rms_z(np.zeros(3), np.zeros((3, 3))) == (pytest.approx(np.nan, nan_ok=True), 0)


def _calibration(bias, matrix, covariance) -> SensorCalibration:
    cov21 = uncertainty.calibration_covariance(bias, matrix, covariance)
    return SensorCalibration("acc", bias, matrix, "m/s^2", uncertainty.std_of(cov21), "test", cov21)


def test_per_parameter_z_is_the_difference_over_the_root_sum_of_variances():
    rng = np.random.default_rng(1)
    ca, cb = np.diag(rng.uniform(1e-4, 4e-4, 12)), np.diag(rng.uniform(1e-4, 4e-4, 12))
    a = _calibration(np.array([0.1, 0.2, 0.3]), np.eye(3) * 1.01, ca)
    b = _calibration(np.array([0.12, 0.19, 0.33]), np.eye(3) * 1.02, cb)
    out = compare_parts(a, b)
    expected = (0.1 - 0.12) / np.sqrt(ca[0, 0] + cb[0, 0])
    assert out["z"]["bias_x"] == pytest.approx(expected, rel=1e-9)
    expected = (1.01 - 1.02) / np.sqrt(ca[3, 3] + cb[3, 3])
    assert out["z"]["matrix_xx"] == pytest.approx(expected, rel=1e-9)
    # a diagonal covariance: the bias group's RMS z is the RMS of its three z
    bias_z = np.array([out["z"][f"bias_{a}"] for a in "xyz"])
    assert out["groups"]["bias"]["rms_z"] == pytest.approx(np.sqrt(np.mean(bias_z**2)))
    assert out["groups"]["bias"]["rank"] == 3 and out["groups"]["all"]["rank"] == 12


def test_inflation_scales_each_group_and_keeps_one_covariance():
    rng = np.random.default_rng(2)
    cal = _calibration(np.zeros(3), np.eye(3), _random_covariance(rng, 12) * 1e-6)
    out = inflate(cal, {"bias": 2.0, "matrix": 3.0})
    np.testing.assert_allclose(out.std["bias"], 2.0 * cal.std["bias"])
    np.testing.assert_allclose(out.std["matrix"], 3.0 * cal.std["matrix"])
    np.testing.assert_allclose(out.std["scale"], 3.0 * cal.std["scale"])
    # bias-matrix covariance scaled by both factors: D C D
    np.testing.assert_allclose(out.covariance[0, 3], 6.0 * cal.covariance[0, 3])
    assert np.linalg.eigvalsh(out.covariance).min() > -1e-15
    assert out.quality["parts (bias)"]["inflation"] == pytest.approx(4.0)
    # a calibration with standard deviations only (the gyroscope's bias alone)
    bias_only = SensorCalibration("gyr", np.zeros(3), np.eye(3), "rad/s", {"bias": np.ones(3)})
    assert np.all(inflate(bias_only, {"bias": 1.7, "matrix": 1.0}).std["bias"] == 1.7)
    assert sensor_covariance(bias_only)[3:, 3:].max() == 0.0  # the matrix is not estimated


def _recording(n: int = 1000) -> tuple[dict, pd.DataFrame]:
    t = np.arange(n) / 100.0
    # the gyroscope's columns count the rows (the cuts are checked on them); no accelerometer
    # sample (the made-up part fits below are not fitted to any, so nothing is held out)
    table = pd.DataFrame({TIME: t, **{c: np.arange(n, dtype=float) for c in GYR}})
    table[list(ACC)] = np.nan
    bounds = [(0, 200, "static"), (300, 400, "static"), (450, 600, "static"), (700, 900, "static")]
    rows = [segment_row("poses", f"s{k}", kind, t, a, b) for k, (a, b, kind) in enumerate(bounds)]
    return {"poses": table}, segments_frame(rows)


def test_halves_are_two_recordings_that_share_no_sample():
    tables, segments = _recording()
    (first, seg_a), (second, seg_b) = split_session(tables, segments, "halves")
    a, b = first["poses"], second["poses"]
    # cut at the middle of the middle rest (of four, the third: 450-600)
    assert len(a) == 525 and len(b) == 475
    np.testing.assert_array_equal(np.concatenate([a[GYR[0]], b[GYR[0]]]), np.arange(1000.0))
    # every segment holds the same samples as in the whole recording, the rest across the cut
    # in two pieces of one label
    assert seg_a["label"].tolist() == ["s0", "s1", "s2"]
    assert seg_b["label"].tolist() == ["s2", "s3"]
    for table, rows in ((a, seg_a), (b, seg_b)):
        for row in rows.itertuples():
            values = table[GYR[0]].to_numpy()[row.start_index : row.end_index]
            assert values[0] == row.start_s * 100 and values[-1] == pytest.approx(row.end_s * 100)


def test_within_gives_each_part_half_of_every_segment_and_motion():
    tables, segments = _recording()
    (first, seg_a), (second, seg_b) = split_session(tables, segments, "within")
    a, b = first["poses"][GYR[0]].to_numpy(), second["poses"][GYR[0]].to_numpy()
    assert not np.any(np.isfinite(a) & np.isfinite(b))  # no sample in both
    assert np.all(np.isfinite(a) | np.isfinite(b))  # none lost
    assert seg_a["end_index"].tolist() == [100, 350, 525, 800]
    assert seg_b["start_index"].tolist() == [100, 350, 525, 800]
    for table, rows in ((a, seg_a), (b, seg_b)):
        for row in rows.itertuples():
            assert np.isfinite(table[row.start_index : row.end_index]).all()


def _fake_fits(z_bias: float, z_matrix: float, seed: int = 0) -> tuple[PartFit, PartFit]:
    """Two parts' calibrations whose difference is ``z`` standard deviations in every
    parameter of a group (diagonal covariance)."""
    rng = np.random.default_rng(seed)
    variance = np.full(12, 1e-4)
    difference = np.sqrt(2 * variance) * np.r_[np.full(3, z_bias), np.full(9, z_matrix)]
    base = np.r_[rng.normal(0, 0.1, 3), np.eye(3).ravel()]
    a = _calibration(base[:3], base[3:].reshape(3, 3), np.diag(variance))
    other = base + difference
    b = _calibration(other[:3], other[3:].reshape(3, 3), np.diag(variance))
    return PartFit("acc_cube", a), PartFit("acc_cube", b)


def _check(fits, shipped, own=None) -> dict:
    tables, segments = _recording()
    return check_parts(
        lambda t, s: {"acc": fits.pop(0)} if fits else {},
        tables,
        segments,
        {"acc": shipped},
        gravity_m_s2=9.81,
        field_norm=1.0,
        own=own,
    )


def test_parts_that_agree_within_their_std_change_nothing():
    a, b = _fake_fits(1.0, 1.0)
    check = _check([a, b], a)
    entry = check["sensors"]["acc"]
    assert entry["parts"]["groups"]["bias"]["rms_z"] == pytest.approx(1.0, rel=1e-6)
    assert entry["inflation"] == {"bias": 1.0, "matrix": 1.0}
    shipped = ship({"acc": a.calibration.to_dict()}, check)["acc"]
    np.testing.assert_allclose(shipped["std"]["bias"], a.calibration.std["bias"])


def test_parts_beyond_the_limit_inflate_the_group_by_its_excess_and_warn():
    a, b = _fake_fits(3.0, 1.0)
    check = _check([a, b], a)
    entry = check["sensors"]["acc"]
    assert entry["inflation"]["bias"] == pytest.approx(3.0, rel=1e-6)
    assert entry["inflation"]["matrix"] == 1.0
    assert entry["parts"]["groups_after"]["bias"]["rms_z"] == pytest.approx(1.0, rel=1e-6)
    assert any("its bias differs between two independent parts" in w for w in entry["warnings"])
    shipped = ship({"acc": a.calibration.to_dict(), "format_version": 2}, check)
    np.testing.assert_allclose(shipped["acc"]["std"]["bias"], 3.0 * a.calibration.std["bias"])
    assert shipped["acc"]["warnings"] == entry["warnings"] and shipped["format_version"] == 2
    # just under the limit: nothing
    a, b = _fake_fits(0.99 * RMS_Z_LIMIT, 1.0)
    assert _check([a, b], a)["sensors"]["acc"]["inflation"]["bias"] == 1.0
    # over it, but as chance gives it on three parameters (p = 0.06): inflated, not warned
    a, b = _fake_fits(1.6, 1.0)
    entry = _check([a, b], a)["sensors"]["acc"]
    assert entry["inflation"]["bias"] == pytest.approx(1.6, rel=1e-6)
    assert entry["parts"]["groups"]["bias"]["p_value"] > SIGNIFICANT_P
    assert entry["warnings"] == []


def test_bias_and_matrix_beyond_the_limit_together_inflate_both():
    # each group within its std, their difference along a direction the correlation forbids
    rng = np.random.default_rng(3)
    corr = np.eye(12)
    corr[0, 3] = corr[3, 0] = 0.99  # bias x and matrix xx nearly move together
    variance = np.full(12, 1e-4)
    covariance = corr * np.sqrt(np.outer(variance, variance))
    base = np.r_[rng.normal(0, 0.1, 3), np.eye(3).ravel()]
    step = np.zeros(12)
    step[0], step[3] = 1e-2, -1e-2  # against the correlation: 1 std each, far jointly
    a = _calibration(base[:3], base[3:].reshape(3, 3), covariance / 2)
    b = _calibration((base + step)[:3], (base + step)[3:].reshape(3, 3), covariance / 2)
    entry = _check([PartFit("acc_cube", a), PartFit("acc_cube", b)], PartFit("acc_cube", a))
    entry = entry["sensors"]["acc"]
    groups = entry["parts"]["groups"]
    assert groups["bias"]["rms_z"] < RMS_Z_LIMIT and groups["matrix"]["rms_z"] < RMS_Z_LIMIT
    assert groups["all"]["rms_z"] > 2 * RMS_Z_LIMIT
    assert entry["inflation"]["bias"] == pytest.approx(entry["inflation"]["matrix"])
    assert entry["parts"]["groups_after"]["all"]["rms_z"] == pytest.approx(1.0, rel=1e-6)
    assert any("bias and matrix together" in w for w in entry["warnings"])


def test_a_fit_whose_parts_cannot_run_warns_unless_its_poses_were_left_out():
    a, _ = _fake_fits(1.0, 1.0)
    entry = _check([], a)["sensors"]["acc"]
    assert "halves: part 1 shipped nothing" in entry["reason"]
    assert any("could not be checked on independent parts" in w for w in entry["warnings"])
    loo = {"rms_z": 2.5, "max_abs_z": 5.0, "n": 10, "basis": "each of 10 poses left out"}
    heldout = {"calibrated": 0.36, "nominal": 0.39, "ratio": 0.36 / 0.39, "basis": loo["basis"]}
    entry = _check([], a, {"acc": {"leave_one_out": loo, "heldout": heldout}})["sensors"]["acc"]
    assert entry["inflation"] == {"bias": 2.5, "matrix": 2.5}
    assert not any("could not be checked" in w for w in entry["warnings"])
    assert any("barely beats the nominal calibration" in w for w in entry["warnings"])
    assert 0.36 / 0.39 > HELDOUT_RATIO
    # the same RMS z with no pose beyond chance (the largest 2.5 of 10: p = 0.12) inflates nothing
    loo["max_abs_z"] = 2.5
    entry = _check([], a, {"acc": {"leave_one_out": loo}})["sensors"]["acc"]
    assert entry["inflation"] == {"bias": 1.0, "matrix": 1.0}


def test_heldout_errors_are_the_rms_of_each_rest_under_the_calibration():
    from imucal.validation.consistency import heldout_errors

    t = np.arange(400) / 100.0
    means = np.array([[0.0, 0.0, 10.0], [0.0, 9.5, 0.0]])
    acc = np.repeat(means, 200, axis=0)
    table = pd.DataFrame({TIME: t, **{c: acc[:, k] for k, c in enumerate(ACC)}})
    segments = segments_frame(
        [
            segment_row("poses", "s1", "static", t, 0, 200),
            segment_row("poses", "s2", "static", t, 200, 400),
        ]
    )
    cal = SensorCalibration("acc", np.zeros(3), np.diag([1.0, 1.02, 0.98]), "m/s^2")
    after, before = heldout_errors(
        "acc", cal, ({"poses": table}, segments), gravity_m_s2=9.81, field_norm=1.0
    )
    assert before == pytest.approx(np.sqrt(np.mean(np.array([0.19, -0.31]) ** 2)))
    assert after == pytest.approx(np.sqrt(np.mean(np.array([9.8 - 9.81, 9.69 - 9.81]) ** 2)))
    assert heldout_errors(
        "acc", cal, ({"poses": table}, segments), gravity_m_s2=9.81, field_norm=1.0,
        recordings=["cube"],
    ) is None  # fmt: skip


def test_faces_left_out_are_normal_scores_of_their_f_tail():
    from scipy import stats

    from imucal.pipeline.parts import left_out

    rng = np.random.default_rng(4)
    # under the model each face's z2 / 3 is F(3, 3) (its held-out fit's tilt from 3 dof)
    z2 = 3 * stats.f.rvs(3, 3, size=6000, random_state=rng)
    found = left_out("acc_known_orientation", {"heldout_z2": z2.tolist(), "dof": 6})
    assert found["leave_one_out"]["n"] == 6000
    assert found["leave_one_out"]["rms_z"] == pytest.approx(1.0, abs=0.05)
    # the same z2 read as chi-square(3) would call the model wrong
    assert np.sqrt(np.mean(z2) / 3) > 1.5
