"""Error model (eqs. 1-11): compose/decompose round trip, small-angle vs exact, apply/invert."""

from __future__ import annotations

import json

import numpy as np
import pytest

from imucal import errormodel


def random_parameters(rng: np.random.Generator, angle_rad: float = 0.03):
    scale = rng.uniform(0.9, 1.2, 3)
    xi = rng.uniform(-angle_rad, angle_rad, 3)
    alpha = rng.uniform(-angle_rad, angle_rad, 3)
    return scale, xi, alpha


def test_compose_decompose_round_trip():
    rng = np.random.default_rng(1)
    for _ in range(100):
        scale, xi, alpha = random_parameters(rng, angle_rad=0.3)
        d = errormodel.decompose(errormodel.compose(scale, xi, alpha))
        # exact algebra: only floating-point round-off remains
        np.testing.assert_allclose(d.scale, scale, atol=1e-12)
        np.testing.assert_allclose(d.xi_rad, xi, atol=1e-12)
        np.testing.assert_allclose(d.alpha_rad, alpha, atol=1e-12)


def test_decompose_matches_conformance_truth(conformance_dir):
    truth = json.loads((conformance_dir / "truth.json").read_text())
    for sensor in ("acc", "gyr", "mag"):
        d = errormodel.decompose(np.array(truth[sensor]["matrix"]))
        np.testing.assert_allclose(d.scale, truth[sensor]["scale"], atol=1e-12)
        np.testing.assert_allclose(d.xi_rad, truth[sensor]["xi"], atol=1e-12)
        np.testing.assert_allclose(d.alpha_rad, truth[sensor]["alpha"], atol=1e-12)


def test_small_angle_form_is_first_order():
    # The error of I + [a]x against the exact rotation is second order: |a|^2 / 2.
    for angle in (0.001, 0.01, 0.05, 0.1):
        alpha = np.array([1.0, -2.0, 0.5]) / np.sqrt(5.25) * angle
        exact = errormodel.rotation_matrix(alpha, exact=True)
        small = errormodel.rotation_matrix(alpha, exact=False)
        err = np.abs(exact - small).max()
        assert err <= angle**2 / 2 * 1.01
        assert err >= angle**2 / 2 * 0.2


def test_small_angle_matrix_is_paper_eq5():
    ax, ay, az = 0.01, -0.02, 0.03
    expected = np.array([[1, -az, ay], [az, 1, -ax], [-ay, ax, 1]])
    np.testing.assert_array_equal(errormodel.rotation_matrix([ax, ay, az], exact=False), expected)


def test_nonorthogonality_matrix_is_paper_eq6():
    xx, xy, xz = 0.01, 0.02, 0.03
    expected = np.array([[1, xz, -xy], [0, 1, xx], [0, 0, 1]])
    np.testing.assert_array_equal(errormodel.nonorthogonality_matrix([xx, xy, xz]), expected)


def test_apply_invert_round_trip():
    rng = np.random.default_rng(2)
    matrix = errormodel.compose(*random_parameters(rng))
    bias = rng.normal(0, 0.2, 3)
    true = rng.normal(0, 9.81, (50, 3))
    readings = errormodel.invert(matrix, bias, true)
    np.testing.assert_allclose(errormodel.apply(matrix, bias, readings), true, atol=1e-12)


def test_upper_triangular_factor_refuses_mirror():
    with pytest.raises(ValueError, match="positive determinant"):
        errormodel.upper_triangular_factor(np.diag([1.0, 1.0, -1.0]))


def test_compose_small_angle_form_and_column_inputs():
    """exact=False composes with the small-angle T_R (eq. 5); scale and angles may come as
    columns (3, 1)."""
    scale, xi, alpha = [1.05, 0.97, 1.01], [0.01, -0.02, 0.015], [0.2, -0.1, 0.3]
    shape = errormodel.nonorthogonality_matrix(xi) @ np.diag(scale)
    small = errormodel.compose(scale, xi, alpha, exact=False)
    np.testing.assert_allclose(small, errormodel.rotation_matrix(alpha, exact=False) @ shape)
    assert np.abs(small - errormodel.compose(scale, xi, alpha)).max() > 1e-3
    column = errormodel.compose(np.c_[scale], np.c_[xi], np.c_[alpha])
    np.testing.assert_array_equal(column, errormodel.compose(scale, xi, alpha))


def test_upper_triangular_factor_refuses_a_singular_matrix():
    with pytest.raises(ValueError):
        errormodel.upper_triangular_factor(np.diag([1.0, 1.0, 0.0]))


def test_rotation_matrix_is_exact_by_default():
    from scipy.spatial.transform import Rotation

    alpha = np.array([0.3, -0.2, 0.25])
    np.testing.assert_allclose(
        errormodel.rotation_matrix(alpha), Rotation.from_rotvec(alpha).as_matrix(), atol=1e-12
    )
