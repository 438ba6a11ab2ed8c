"""Known-orientation accelerometer and known-angle gyroscope fits: recovery of truth, refusals."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import z_limit
from scipy.spatial.transform import Rotation

from imucal import errormodel
from imucal.fits.ferraris import (
    FACE_DIRECTIONS,
    fit_known_orientations,
    fit_known_rotations,
    heldout_positions,
)

G = 9.81
ACC_NOISE = 0.02  # m/s^2 per axis and sample
PLACEMENT = 0.003  # rad: how far a hand-placed face tilts from its nominal direction (std)
N_SAMPLES = 500
RATE_HZ = 100.0
GYR_NOISE = 0.005  # rad/s
GYR_BIAS = np.array([0.03, -0.02, 0.01])


def acc_truth() -> tuple[np.ndarray, np.ndarray]:
    return errormodel.compose([0.98, 1.01, 1.02], [0.01, -0.02, 0.015], [0.01, 0.02, -0.01]), (
        np.array([0.1, -0.2, 0.3])
    )


def gyr_truth() -> np.ndarray:
    return errormodel.compose([1.1, 0.95, 1.03], [0.01, 0.005, -0.01], [0.015, -0.02, 0.01])


def face_positions(rng, directions, placement=PLACEMENT):
    matrix, bias = acc_truth()
    out = []
    for d in directions:
        tilt = Rotation.from_rotvec(placement * rng.standard_normal(3))
        up = tilt.apply(d)
        out.append(
            errormodel.invert(matrix, bias, np.tile(G * up, (N_SAMPLES, 1)))
            + ACC_NOISE * rng.standard_normal((N_SAMPLES, 3))
        )
    return out


def test_six_faces_recover_matrix_and_bias_within_their_std():
    rng = np.random.default_rng(21)
    labels = list(FACE_DIRECTIONS)
    directions = np.array([FACE_DIRECTIONS[k] for k in labels])
    fit = fit_known_orientations(face_positions(rng, directions), directions, G, labels=labels)
    matrix, bias = acc_truth()
    cal = fit.calibration
    # per-position error: placement tilt g * 0.003 = 0.03 m/s^2 across gravity, sample noise
    # 0.02 / sqrt(500) = 1e-3; the residual std must see the placement, not the sample noise
    assert 0.01 < fit.residual_std_m_s2 < 0.06
    assert fit.dof == 6
    # 6 dof only: the std is itself uncertain by ~30 %, an error over it Student's t(6); the
    # bound holds the 15 errors below (bias, matrix, alpha) at 1e-4
    z = z_limit(15, dof=6)
    assert np.all(np.abs(cal.bias - bias) < z * cal.std["bias"]), cal.bias - bias
    assert np.all(np.abs(cal.matrix - matrix) < z * cal.std["matrix"])
    # the std is that of a placement error of 0.03 m/s^2 on ~2 g lever: ~1e-3 relative
    assert np.all(cal.std["matrix"] < 5e-3)
    # the rotation into B is recovered too (not only the upper-triangular part)
    truth = errormodel.decompose(matrix)
    assert np.all(np.abs(cal.decomposition.alpha_rad - truth.alpha_rad) < z * cal.std["alpha_rad"])
    assert np.max(np.abs(fit.magnitude_error_m_s2)) < 0.1


def test_exactly_placed_faces_leave_only_sample_noise():
    rng = np.random.default_rng(22)
    directions = np.array(list(FACE_DIRECTIONS.values()))
    fit = fit_known_orientations(face_positions(rng, directions, placement=0.0), directions, G)
    matrix, bias = acc_truth()
    # mean of 500 samples: 0.02 / sqrt(500) = 9e-4 m/s^2 per axis; bias from 2 faces per axis
    # ~ 6e-4; 5 std = 3e-3 m/s^2; matrix entries ~ 9e-4 / (2 g) ~ 5e-5 -> 5 std ~ 3e-4
    assert np.max(np.abs(fit.calibration.bias - bias)) < 3e-3
    assert np.max(np.abs(fit.calibration.matrix - matrix)) < 3e-4


def test_heldout_faces_are_as_far_off_as_their_predicted_covariance():
    # each face against the fit on the other five (3 dof: the placement tilt is estimated from
    # 3 residuals), over 60 sessions: with the tilt dominating, z2 / 3 follows F(3, 3), whose
    # median is 1; half of the 360 values below it, binomial std 0.026 (fewer are independent,
    # about 200: 0.035), 3.4 of them bound the share
    directions = np.array(list(FACE_DIRECTIONS.values()))
    z2 = np.concatenate(
        [heldout_positions(face_positions(np.random.default_rng(200 + k), directions),
                           directions, G).z2 for k in range(60)]
    )  # fmt: skip
    assert 0.38 < np.mean(z2 / 3 < 1.0) < 0.62
    with pytest.raises(ValueError, match="at least 6"):
        heldout_positions(face_positions(np.random.default_rng(1), directions[:5]),
                          directions[:5], G)  # fmt: skip


def test_acc_refusals():
    rng = np.random.default_rng(23)
    directions = np.array(list(FACE_DIRECTIONS.values()))
    positions = face_positions(rng, directions)
    with pytest.raises(ValueError, match=r"at least 4 positions.*got 3"):
        fit_known_orientations(positions[:3], directions[:3], G)
    # x up, x down, y up, y down: the z axis is never excited
    with pytest.raises(ValueError, match=r"do not span 3-D"):
        fit_known_orientations(positions[:4], directions[:4], G)
    with pytest.raises(ValueError, match=r"directions of shape \(6, 3\)"):
        fit_known_orientations(positions, directions[:5], G)
    swapped = directions.copy()
    swapped[[0, 1]] = swapped[[1, 0]]  # x_p and x_a labels exchanged
    with pytest.raises(ValueError, match=r"mirrors the axes"):
        fit_known_orientations(positions, swapped, G)
    positions[2][5, 0] = np.nan
    with pytest.raises(ValueError, match=r"position 'p03': 1 rows not finite"):
        fit_known_orientations(positions, directions, G)


def rotation_sections(rng, angles_rad, irregular=False, matrix=None):
    """One section per known rotation vector: smooth turn about a fixed body axis, at rest at
    both ends, raw = M^-1 omega + bias + noise."""
    matrix = gyr_truth() if matrix is None else matrix
    out = []
    for theta in angles_rad:
        duration = 4.0
        n = int(duration * RATE_HZ)
        if irregular:
            t = np.concatenate([[0.0], np.cumsum(rng.uniform(0.5, 1.5, n))])
            t *= duration / t[-1]
        else:
            t = np.linspace(0.0, duration, n + 1)
        # cycloidal profile: rate theta / T (1 - cos(2 pi t / T))
        omega = np.outer(1 - np.cos(2 * np.pi * t / duration), np.asarray(theta) / duration)
        raw = errormodel.invert(matrix, GYR_BIAS, omega)
        out.append((t, raw + GYR_NOISE * rng.standard_normal(raw.shape)))
    return out


@pytest.mark.parametrize("irregular", [False, True])
def test_known_rotations_recover_gyro_matrix(irregular):
    rng = np.random.default_rng(31 + irregular)
    known = -2 * np.pi * np.eye(3)  # clockwise 360 degrees about x, y, z of B
    sections = rotation_sections(rng, known, irregular)
    fit = fit_known_rotations(
        sections,
        known,
        GYR_BIAS,
        noise_std_rad_s=np.full(3, GYR_NOISE),
        bias_std_rad_s=np.full(3, 1e-4),
        labels=["x_rot", "y_rot", "z_rot"],
    )
    cal = fit.calibration
    # integrated noise: 0.005 rad/s * sqrt(4 s * 0.01 s) = 1e-3 rad per axis, plus the bias std
    # 1e-4 rad/s * 4 s = 4e-4 rad; over 2 pi: ~2e-4 per matrix entry; the propagated std must
    # say so, and the 9 errors lie within the bound of 9 normal errors at 1e-4 of it
    assert np.all(cal.std["matrix"] < 4e-4) and np.all(cal.std["matrix"] > 5e-5)
    assert np.all(np.abs(cal.matrix - gyr_truth()) < z_limit(9) * cal.std["matrix"])
    # three sections determine the 9 entries exactly: no in-sample residual
    assert np.max(np.abs(fit.residuals_rad)) < 1e-9
    assert np.allclose(fit.durations_s, 4.0)


def test_redundant_rotations_give_residuals():
    rng = np.random.default_rng(33)
    known = np.vstack([-2 * np.pi * np.eye(3), 2 * np.pi * np.eye(3)])  # both senses
    fit = fit_known_rotations(rotation_sections(rng, known), known, GYR_BIAS)
    # residual per axis ~ integrated noise 1e-3 rad (not 0, not degrees)
    assert 1e-4 < np.max(np.abs(fit.residuals_rad)) < 6e-3
    assert np.max(np.abs(fit.calibration.matrix - gyr_truth())) < 1e-3


def test_gyro_refusals():
    rng = np.random.default_rng(34)
    known = -2 * np.pi * np.eye(3)
    sections = rotation_sections(rng, known)
    with pytest.raises(ValueError, match=r"at least 3 rotation sections.*got 2"):
        fit_known_rotations(sections[:2], known[:2], GYR_BIAS)
    # wrong sense on every axis: the matrix would mirror
    with pytest.raises(ValueError, match=r"mirrors the axes.*clockwise is negative"):
        fit_known_rotations(sections, -known, GYR_BIAS)
    # the third "rotation" turned about x again: y, z and x only span a plane
    same_axis = rotation_sections(rng, [known[0], known[1], known[0]])
    with pytest.raises(ValueError, match=r"raw angle vectors .* do not span 3-D"):
        fit_known_rotations(same_axis, known, GYR_BIAS)
    t, w = sections[1]
    with pytest.raises(ValueError, match=r"rotation 'r02': timestamps must increase"):
        fit_known_rotations([sections[0], (t[::-1], w), sections[2]], known, GYR_BIAS)


def test_tilt_weighting_estimates_placement_and_sharpens_the_bias():
    rng = np.random.default_rng(24)
    directions = np.array(list(FACE_DIRECTIONS.values()))
    positions = face_positions(rng, directions)
    _, bias = acc_truth()
    tilt = fit_known_orientations(positions, directions, G, weighting="tilt")
    equal = fit_known_orientations(positions, directions, G, weighting="equal")
    # tau from a chi-square with 6 dof: relative scatter ~ 1 / sqrt(2 * 6) ~ 30 %; 0.003 injected
    assert 0.0012 < tilt.placement_std_rad < 0.006
    assert equal.placement_std_rad == 0.0
    # with the tilt modelled the bias comes from the two faces with the axis vertical: sample
    # noise 0.02 / sqrt(500) / sqrt(2) = 6e-4 m/s^2 (tilt enters only as g tau^2 / 2 = 4e-5);
    # equal weights mix in g * tau = 0.03 m/s^2 from the four horizontal faces: std ~ 0.01
    assert np.all(tilt.calibration.std["bias"] < 2e-3)
    assert np.all(equal.calibration.std["bias"] > 4e-3)
    assert np.all(np.abs(tilt.calibration.bias - bias) < z_limit(3) * tilt.calibration.std["bias"])
    with pytest.raises(ValueError, match=r"weighting must be one of"):
        fit_known_orientations(positions, directions, G, weighting="robust")


def test_known_rotations_covariance_with_the_bias_is_honest():
    """The bias given with its std is drawn about the truth; the (bias, matrix) error's
    Mahalanobis distance with the 12 x 12 covariance (bias-matrix cross terms included) summed
    over 20 seeds lies in the 99.9 % interval of chi-square(240)."""
    from scipy import stats

    bias_std = 2e-4
    known = -2 * np.pi * np.eye(3)
    total = 0.0
    for seed in range(20):
        rng = np.random.default_rng(400 + seed)
        sections = rotation_sections(rng, known)
        bias = GYR_BIAS + bias_std * rng.standard_normal(3)
        cal = fit_known_rotations(
            sections,
            known,
            bias,
            noise_std_rad_s=np.full(3, GYR_NOISE),
            bias_std_rad_s=np.full(3, bias_std),
        ).calibration
        err = np.r_[cal.bias - GYR_BIAS, (cal.matrix - gyr_truth()).ravel()]
        total += float(err @ np.linalg.solve(cal.covariance[:12, :12], err))
    low, high = stats.chi2.ppf([0.0005, 0.9995], 240)
    assert low < total < high, (total, low, high)


def test_equal_weights_report_the_least_squares_std_of_every_entry():
    """Equal weights on the six faces: each row (A[i, :], o[i]) of ``reading = A g d + o`` is
    an ordinary least-squares fit whose design has +-g on two faces per column, so every entry
    of A has variance s^2 / (2 g^2), independent of the others, and each bias s^2 / 6 (s the
    pooled residual std). The calibration matrix M = A^-1 moves by dM = -M dA M, so to first
    order var(M_ij) = sum_kl (M_ik M_lj)^2 s^2 / (2 g^2): the reported stds, entry by entry."""
    rng = np.random.default_rng(24)
    directions = np.array(list(FACE_DIRECTIONS.values()))
    fit = fit_known_orientations(face_positions(rng, directions), directions, G, weighting="equal")
    s = fit.residual_std_m_s2
    m = fit.calibration.matrix
    var_m = (m**2) @ np.full((3, 3), s**2 / (2 * G**2)) @ (m**2)
    np.testing.assert_allclose(fit.calibration.std["bias"], np.full(3, s / np.sqrt(6)), rtol=1e-6)
    np.testing.assert_allclose(fit.calibration.std["matrix"], np.sqrt(var_m), rtol=1e-3)
