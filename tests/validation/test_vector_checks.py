"""Vector comparisons: their shape checks, the dip angle's scatter and the weighted mounting's
error against its reported std."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from imucal.validation.consistency import group_rms_z
from imucal.validation.metrics import compare_vectors, summarise_dip
from imucal.validation.mounting import estimate_mounting


@pytest.mark.parametrize(
    ("a", "b"), [((5, 2), (5, 2)), ((5, 3), (4, 3)), ((5,), (5,))], ids=["width", "rows", "1d"]
)
def test_vectors_of_another_shape_are_refused(a, b):
    with pytest.raises(ValueError, match=r"\(n, 3\)"):
        compare_vectors(np.ones(a), np.ones(b))
    with pytest.raises(ValueError, match=r"\(n, 3\)"):
        estimate_mounting({"acc": np.ones(a)}, {"acc": np.ones(b)})


def _at_angles(deg: list[float]) -> tuple[np.ndarray, np.ndarray]:
    """Specific force along z and a field at the given angles from it, in the x-z plane."""
    rad = np.radians(deg)
    acc = np.tile([0.0, 0.0, 9.81], (len(deg), 1))
    mag = 50.0 * np.column_stack([np.sin(rad), np.zeros(len(deg)), np.cos(rad)])
    return acc, mag


def test_the_dip_scatter_is_the_sample_std_of_the_angles():
    """Angles 30, 31, 32 deg: mean 31, sample std (n - 1) exactly 1; two rows 30 and 32 deg
    are enough for a std (sqrt 2); one row has none."""
    acc, mag = _at_angles([30.0, 31.0, 32.0])
    out = summarise_dip(acc, mag, np.ones(3, dtype=bool))
    assert out["n"] == 3
    assert out["mean_deg"] == pytest.approx(31.0, abs=1e-9)
    assert out["std_deg"] == pytest.approx(1.0, abs=1e-9)
    acc, mag = _at_angles([30.0, 32.0])
    assert summarise_dip(acc, mag, np.ones(2, dtype=bool))["std_deg"] == pytest.approx(
        np.sqrt(2.0), abs=1e-9
    )
    assert np.isnan(summarise_dip(acc[:1], mag[:1], np.ones(1, dtype=bool))["std_deg"])


def test_a_precise_sensor_beside_a_noisy_one_sets_the_mounting_within_its_std(z_bound):
    """Accelerometer vectors (9.81 m/s^2) with 0.01 m/s^2 of noise beside gyroscope vectors
    (1 rad/s) with 0.05 rad/s: weighting each sensor by its inverse residual variance lets the
    accelerometer fix the rotation. The rotation vector's error e has |e|^2 = sum l_i z_i^2 <=
    trace(cov) max z_i^2 (l_i the eigenvalues of its covariance), so |e| stays within
    ``angle_std`` times the bound of three normal errors, the std being the accelerometer's:
    sigma / (|v| sqrt(2 n / 3)) per axis. Weighting the noisy sensor instead puts the error
    beyond that bound."""
    rng = np.random.default_rng(11)
    truth = Rotation.from_rotvec([0.02, -0.03, 0.05])
    n, sigma_acc = 300, 0.01
    ref_acc = rng.normal(size=(n, 3))
    ref_acc *= 9.81 / np.linalg.norm(ref_acc, axis=1, keepdims=True)
    ref_gyr = rng.normal(size=(n, 3))
    ref_gyr /= np.linalg.norm(ref_gyr, axis=1, keepdims=True)
    acc = truth.apply(ref_acc) + rng.normal(0.0, sigma_acc, (n, 3))
    gyr = truth.apply(ref_gyr) + rng.normal(0.0, 0.05, (n, 3))
    m = estimate_mounting({"acc": acc, "gyr": gyr}, {"acc": ref_acc, "gyr": ref_gyr})
    error = Rotation.from_matrix(m.matrix) * truth.inv()
    angle_deg = np.degrees(np.linalg.norm(error.as_rotvec()))
    assert angle_deg <= z_bound(3) * m.angle_std_deg
    expected = np.degrees(np.sqrt(3) * sigma_acc / (9.81 * np.sqrt(2 * n / 3)))
    # the gyroscope adds under 1 % of the information; the residual RMS that sets the weight
    # is itself estimated from 900 components (2.4 % standard error)
    assert m.angle_std_deg == pytest.approx(expected, rel=0.1)


def test_the_whitened_difference_of_one_parameter_is_its_z():
    """One parameter of variance 4 differing by 2: RMS z 1 of rank 1; by 6 of variance 4 and
    9 for a pair (independent): sqrt((9 + 9) / 2) = 3; nothing estimated: no score."""
    assert group_rms_z(np.array([2.0]), np.array([[4.0]])) == pytest.approx((1.0, 1))
    rms, rank = group_rms_z(np.array([6.0, 9.0]), np.diag([4.0, 9.0]))
    assert rank == 2 and rms == pytest.approx(np.sqrt((9.0 + 9.0) / 2))
    rms, rank = group_rms_z(np.array([1.0]), np.zeros((1, 1)))
    assert rank == 0 and np.isnan(rms)
