"""Gyroscope calibration against an orientation reference on simulated sessions."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from imucal import errormodel
from imucal.fits.reference import fit_gyro_to_reference
from imucal.sim.orientation import simulate_orientation_session
from imucal.validation.orientation import align_orientation_reference, aligned_intervals

MOUNTING = Rotation.from_rotvec([-0.8, 0.2, 2.1]).as_matrix()
BIAS = np.array([0.02, -0.01, 0.015])


@pytest.mark.parametrize("seed", [5, 6])
def test_matrix_bias_and_mounting_recovered(seed):
    rng = np.random.default_rng(seed)
    # scale 3 %, non-orthogonality 0.5 deg: T_R = I by the convention of the fit
    matrix = errormodel.compose(1 + rng.normal(0, 0.03, 3), rng.normal(0, 0.009, 3), np.zeros(3))
    s = simulate_orientation_session(
        seed, matrix=matrix, bias=BIAS, mounting=MOUNTING, offset_s=-1.3, drift_ppm=-25.0
    )
    # the alignment on the bias-corrected raw gyro, as the pipeline does before any calibration
    al = align_orientation_reference(s.t_module, s.gyr - np.median(s.gyr[:200], axis=0),
                                     s.t_reference, s.quat_reference)  # fmt: skip
    readings, rates = aligned_intervals(s.t_module, s.gyr, s.t_reference, s.quat_reference, al)
    fit = fit_gyro_to_reference([readings], [rates])
    error = fit.calibration.matrix - matrix
    assert np.abs(error).max() < 2e-3
    upper = np.triu(np.ones((3, 3), dtype=bool))
    # within 5 of its stated standard deviations (entries of the upper triangle)
    assert np.all(np.abs(error[upper]) < 5 * fit.std_matrix[upper] + 1e-5)
    assert np.all(np.abs(fit.calibration.bias - BIAS) < 5 * fit.calibration.std["bias"])
    mount_error = Rotation.from_matrix(fit.mounting @ MOUNTING.T).as_rotvec()
    assert np.degrees(np.linalg.norm(mount_error)) < 0.1
    assert np.all(np.abs(mount_error) < 5 * fit.mounting_std_rad)
    assert fit.n_outliers < 0.01 * fit.n_intervals


def test_refuses_one_axis_motion_and_too_few_intervals():
    t = np.linspace(0, 10, 500)
    rates = np.column_stack([np.sin(t), np.zeros_like(t), np.zeros_like(t)])
    with pytest.raises(ValueError, match="excites the gyroscope's axes unevenly"):
        fit_gyro_to_reference([rates + 1e-9 * np.cos(3 * t)[:, None]], [rates])
    with pytest.raises(ValueError, match="50 intervals with both rates; expected at least 100"):
        fit_gyro_to_reference([rates[:50]], [rates[:50]])


@pytest.fixture(scope="module")
def reference_z() -> np.ndarray:
    """z of the upper entries of U (6), the bias (3) and the mounting (3) over 8 sessions."""
    z = []
    for seed in range(20, 28):
        rng = np.random.default_rng(seed)
        matrix = errormodel.compose(
            1 + rng.normal(0, 0.03, 3), rng.normal(0, 0.009, 3), np.zeros(3)
        )
        s = simulate_orientation_session(
            seed, matrix=matrix, bias=BIAS, mounting=MOUNTING, offset_s=-1.3, drift_ppm=-25.0
        )
        al = align_orientation_reference(s.t_module, s.gyr - np.median(s.gyr[:200], axis=0),
                                         s.t_reference, s.quat_reference)  # fmt: skip
        readings, rates = aligned_intervals(s.t_module, s.gyr, s.t_reference, s.quat_reference, al)
        fit = fit_gyro_to_reference([readings], [rates])
        upper = np.triu_indices(3)
        mount_error = Rotation.from_matrix(fit.mounting @ MOUNTING.T).as_rotvec()
        z.append(
            np.r_[
                (fit.calibration.matrix - matrix)[upper] / fit.std_matrix[upper],
                (fit.calibration.bias - BIAS) / fit.calibration.std["bias"],
                mount_error / fit.mounting_std_rad,
            ]
        )
    return np.array(z)


def test_reported_std_is_not_smaller_than_the_errors(reference_z, rms_z_band):
    """Over 8 sessions each of the 12 parameters' RMS z below the upper end of the 1 - 1e-4
    interval of 8 standard normal draws (2.3 per parameter at 1e-4 / 12): a std that left out
    the jackknife (the coloured errors of the finite-difference rates) or a factor would show."""
    rms = np.sqrt(np.mean(reference_z**2, axis=0))
    _, high = rms_z_band(reference_z.shape[0], 1e-4 / reference_z.shape[1])
    assert np.all(rms < high), (rms.round(2), high)


@pytest.mark.xfail(
    strict=True,
    reason="the std (the larger of the formal and the delete-a-block jackknife's) overstates the "
    "errors about 5x: RMS z 0.08-0.32 per parameter over 8 sessions",
)
def test_reported_std_is_not_larger_than_the_errors(reference_z, rms_z_band):
    """The 96 z pooled (a session's 12 are not independent, so the interval is only a guide):
    RMS z above the lower end of the 1 - 1e-4 interval of 96 draws (0.73)."""
    rms = float(np.sqrt(np.mean(reference_z**2)))
    low, _ = rms_z_band(reference_z.size, 1e-4)
    assert rms > low, (rms, low)


def test_magnetometer_alignment_std_follows_its_errors():
    """fit_mag_to_reference on 100 draws: 300 random orientations, the field seen through a
    known T_R with noise 0.01 per axis. The jackknife's std comes from a few blocks, so its z
    have a t-like tail (RMS z 1.08-1.17 here); the share of errors within 0.6745 std is
    tested, Binomial(100, 0.5) per axis when the std is right (its 1 - 1e-4 interval over the
    three axes). A std off by a factor 2 leaves about 26 of 100 within."""
    from scipy import stats

    from imucal.fits.reference import fit_mag_to_reference

    alpha = np.array([0.03, -0.02, 0.05])
    to_b = Rotation.from_rotvec(alpha)
    field = np.array([0.4, 0.0, -0.9165]) / np.linalg.norm([0.4, 0.0, -0.9165])
    z = []
    for seed in range(100):
        rng = np.random.default_rng(seed)
        body_to_world = Rotation.random(300, random_state=seed)
        m = to_b.apply(body_to_world.apply(field, inverse=True), inverse=True)
        fit = fit_mag_to_reference(m + 0.01 * rng.standard_normal(m.shape), body_to_world)
        z.append((fit.alpha_rad - alpha) / np.sqrt(np.diag(fit.alpha_covariance)))
    inside = np.sum(np.abs(np.array(z)) < stats.norm.ppf(0.75), axis=0)
    low, high = stats.binom.ppf([1e-4 / 6, 1 - 1e-4 / 6], 100, 0.5)
    assert np.all((low <= inside) & (inside <= high)), (inside, low, high)
