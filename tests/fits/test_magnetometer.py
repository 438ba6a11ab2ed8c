"""Magnetometer steps 1 and 2: known truth recovered, bad data refused, conformance session."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from imucal import errormodel
from imucal.columns import MAG, TIME
from imucal.fits.magnetometer import (
    EllipsoidFit,
    calibrate_alignment,
    field_samples,
    fit_ellipsoid,
)

NOISE = 0.004  # per axis, normalised: the conformance session's residual RMS of |m'| - 1
TRUE_MATRIX = errormodel.compose([1.05, 0.93, 1.02], [0.03, -0.04, 0.02], [0.02, -0.015, 0.025])
TRUE_BIAS = np.array([0.12, -0.25, 0.3])


def field_in_b(n_phase: int = 150, seed: int = 0) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Unit field in B along a rotation3d session: two turns about x, y, z, yaw transitions."""
    rng = np.random.default_rng(seed)
    phases = {}
    for a, (label, c) in enumerate(zip("xyz", (0.35, -0.45, -0.85))):
        phi = np.linspace(0, 4 * np.pi, n_phase, endpoint=False) + rng.uniform(0, 2 * np.pi)
        b, d = (k for k in range(3) if k != a)
        u = np.zeros((n_phase, 3))
        u[:, a], u[:, b], u[:, d] = (
            c,
            np.sqrt(1 - c * c) * np.cos(phi),
            np.sqrt(1 - c * c) * np.sin(phi),
        )
        phases[label] = u
    # yaw transitions: the field turns about z at the platform's rest inclination
    psi = np.linspace(0, np.pi, 90)
    transition = np.column_stack(
        [0.5 * np.cos(psi), 0.5 * np.sin(psi), np.full(90, -np.sqrt(0.75))]
    )
    return np.vstack([*phases.values(), transition]), phases


def readings(u: np.ndarray, noise: float, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return errormodel.invert(TRUE_MATRIX, TRUE_BIAS, u) + rng.normal(0, noise, u.shape)


def true_upper() -> np.ndarray:
    return errormodel.upper_triangular_factor(TRUE_MATRIX)[1]


@pytest.mark.parametrize("refine_lm", [False, True])
def test_step1_exact_without_noise(refine_lm):
    u, _ = field_in_b()
    fit = fit_ellipsoid(readings(u, 0.0, 1), refine_lm=refine_lm)
    # exact algebra on noise-free data: round-off only
    np.testing.assert_allclose(fit.upper, true_upper(), atol=1e-9)
    np.testing.assert_allclose(fit.bias, TRUE_BIAS, atol=1e-9)
    assert fit.used == ("svd+lm" if refine_lm else "svd")


def test_step1_recovers_upper_and_bias_within_noise():
    u, _ = field_in_b()
    m = readings(u, NOISE, 2)
    fit = fit_ellipsoid(m)
    # 9 parameters from n = 540 samples: errors ~ NOISE * sqrt(9 / n) * g with a geometry factor
    # g <= 3 for this coverage (Monte-Carlo, docs/accuracy-magnetometer.md); tolerance 5x that
    tol = 5 * 3 * NOISE * np.sqrt(9 / m.shape[0])
    np.testing.assert_allclose(fit.bias, TRUE_BIAS, atol=tol)
    np.testing.assert_allclose(fit.upper, true_upper(), atol=tol)
    # the reported std must explain the error, and sigma from the residuals is the noise
    assert np.all(np.abs(fit.bias - TRUE_BIAS) < 5 * fit.lm.std_bias)
    assert fit.lm.residual_rms == pytest.approx(NOISE, rel=0.15)  # radial noise / |m| ~ NOISE
    assert np.all(np.isfinite(fit.lm.covariance))
    assert fit.coverage_pct > 20 and fit.condition_number < 1e3


def test_lm_runaway_at_low_coverage_is_refused():
    # directions within 75 degrees of +z only: eq. 17, measured in calibrated units, runs away to
    # a degenerate elongated ellipsoid (its residuals shrink with S'); refused, never returned
    rng = np.random.default_rng(4)
    z = rng.uniform(np.cos(np.radians(75)), 1, 3000)
    lon = rng.uniform(0, 2 * np.pi, 3000)
    u = np.column_stack([np.sqrt(1 - z * z) * np.cos(lon), np.sqrt(1 - z * z) * np.sin(lon), z])
    m = readings(u, 0.02, 5)
    with pytest.raises(ValueError, match="LM refinement of eq. 17 did not converge"):
        fit_ellipsoid(m, min_coverage_pct=10)
    svd = fit_ellipsoid(m, refine_lm=False, min_coverage_pct=10)
    assert np.all(np.isfinite(svd.upper)) and svd.lm is None


def test_field_norm_scales_the_output():
    u, _ = field_in_b()
    m = readings(u, 0.0, 1)
    fit = fit_ellipsoid(48.0 * m, field_norm=48.0)
    # readings in a unit where the field is 48: same S', bias in that unit
    np.testing.assert_allclose(fit.bias, 48.0 * TRUE_BIAS, atol=1e-8)
    np.testing.assert_allclose(np.linalg.norm(fit.apply(48.0 * m), axis=1), 48.0, atol=1e-8)


def test_non_ellipsoid_is_refused():
    rng = np.random.default_rng(6)
    # hyperboloid x^2 + y^2 - z^2 = 1
    z = rng.uniform(-1, 1, 500)
    lon = rng.uniform(0, 2 * np.pi, 500)
    r = np.sqrt(1 + z * z)
    m = np.column_stack([r * np.cos(lon), r * np.sin(lon), z])
    with pytest.raises(ValueError, match="do not describe an ellipsoid: .* mixed sign"):
        fit_ellipsoid(m)


def test_poor_coverage_is_refused_with_numbers():
    _, phases = field_in_b()
    m = readings(np.vstack([phases["x"], phases["y"]]), NOISE, 7)  # two circles only
    with pytest.raises(
        ValueError,
        match=r"cover too little .*coverage of the sphere [\d.]+ %, "
        r"condition number [\d.e+]+",
    ):
        fit_ellipsoid(m)


def test_extra_samples_join_only_in_the_same_field():
    u, _ = field_in_b()
    rng = np.random.default_rng(8)
    cube_u = rng.normal(size=(12, 3))
    cube_u = np.repeat(cube_u / np.linalg.norm(cube_u, axis=1, keepdims=True), 40, axis=0)
    m = readings(u, NOISE, 9)
    same = readings(cube_u, NOISE, 10)
    other = readings(1.05 * cube_u, NOISE, 10)  # a lab whose field is 5 % stronger
    fit = fit_ellipsoid(m, extra_samples={"cube": same})
    assert fit.extra["cube"]["used"] and fit.n_samples == m.shape[0] + same.shape[0]
    fit = fit_ellipsoid(m, extra_samples={"cube": other})
    assert not fit.extra["cube"]["used"] and fit.n_samples == m.shape[0]
    assert fit.extra["cube"]["norm_mismatch"] == pytest.approx(0.05, abs=0.01)


def test_round_trip_through_dict():
    u, _ = field_in_b()
    fit = fit_ellipsoid(readings(u, NOISE, 11))
    back = EllipsoidFit.from_dict(json.loads(json.dumps(fit.to_dict())))
    np.testing.assert_array_equal(back.upper, fit.upper)
    np.testing.assert_array_equal(back.lm.covariance, fit.lm.covariance)
    assert back.coverage_pct == fit.coverage_pct and back.used == fit.used


def test_field_samples_refuses_partial_rows():
    table = pd.DataFrame(
        {
            TIME: [0.0, 0.1, 0.2],
            MAG[0]: [1.0, np.nan, 2.0],
            MAG[1]: [1.0, np.nan, np.nan],
            MAG[2]: [1.0, np.nan, 2.0],
        }
    )
    with pytest.raises(ValueError, match=r"1 rows have some but not all .* row 2 \(t = 0.2 s\)"):
        field_samples(table)
    t, m = field_samples(table.drop(index=2))
    np.testing.assert_array_equal(t, [0.0])
    np.testing.assert_array_equal(m, [[1.0, 1.0, 1.0]])


def test_steps_1_and_2_recover_the_calibration():
    u, _ = field_in_b()
    m = readings(u, NOISE, 12)
    n_phase = 150
    phases = {k: m[i * n_phase : (i + 1) * n_phase] for i, k in enumerate("xyz")}
    result = calibrate_alignment(fit_ellipsoid(m), phases)
    cal = result.calibration
    # as in the step-1 test: 5 x (3 NOISE sqrt(9 / n)); the matrix also carries T_R errors of
    # ~NOISE / (rho sqrt(n_phase / 2)) rad, below that bound
    tol = 5 * 3 * NOISE * np.sqrt(9 / m.shape[0])
    np.testing.assert_allclose(cal.matrix, TRUE_MATRIX, atol=tol)
    np.testing.assert_allclose(cal.bias, TRUE_BIAS, atol=tol)
    assert np.all(np.abs(cal.matrix - TRUE_MATRIX) < 5 * cal.std["matrix"] + 1e-12)
    assert result.method == "full" and set(result.alignments) == {"full", "paper"}
    calibrated_x = cal.apply(phases["x"], "normalised")[:, 0]
    assert np.std(calibrated_x) == pytest.approx(NOISE, rel=0.25)


def conformance_mag(folder, recording: str) -> tuple[np.ndarray, np.ndarray]:
    """Magnetometer samples of a conformance CSV in the normalised unit (counts * sensitivity)."""
    import yaml

    info = yaml.safe_load((folder / "dataset.yaml").read_text())
    table = pd.read_csv(folder / info["recordings"][recording])
    table[list(MAG)] *= info["sensitivity"]["mag"]
    return field_samples(table)


@pytest.mark.parametrize("with_cube", [False, True])
def test_conformance_session(conformance_dir, with_cube):
    truth = json.loads((conformance_dir / "truth.json").read_text())["mag"]
    t, m = conformance_mag(conformance_dir, "rotation3d")
    extra = {"cube": conformance_mag(conformance_dir, "cube")[1]} if with_cube else None
    # phase windows of this session read off its gyroscope by hand: the test is of the fit alone
    windows = {"x": (12.5, 27.5), "y": (39.0, 53.5), "z": (64.5, 76.0)}
    phases = {k: m[(t >= a) & (t < b)] for k, (a, b) in windows.items()}
    fit = fit_ellipsoid(m, extra_samples=extra)
    cal = calibrate_alignment(fit, phases).calibration
    assert np.abs(cal.matrix - np.array(truth["matrix"])).max() < 5e-3
    assert np.abs(cal.bias - np.array(truth["bias"])).max() < 5e-3


def test_static_log_is_refused_with_no_coverage():
    # a magnetometer that does not turn: its noise points everywhere about the mean, which
    # must not read as a covered sphere
    m = np.array([0.3, -0.2, 0.5]) + np.random.default_rng(0).normal(0, 0.01, (2000, 3))
    with pytest.raises(
        ValueError, match=r"do not move beyond their noise, as in a static log: coverage of the "
        r"sphere 0\.0 %"
    ):  # fmt: skip
        fit_ellipsoid(m)
