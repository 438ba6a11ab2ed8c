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
