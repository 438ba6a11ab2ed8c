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


def test_reported_std_follows_the_errors_in_the_unit_of_the_field(rms_z_band):
    """400 sessions read in a unit where the field is 48 (readings and noise times 48): the
    error of each of the 6 entries of S' and the 3 of o over its reported std, for the SVD
    and the LM solution. Each parameter's RMS z must lie in the 99.99 % interval of 400
    standard normal draws (0.86-1.14); a std of S' not scaled by the field norm makes its z
    48 times larger."""
    u, _ = field_in_b()
    field = 48.0
    upper = np.triu_indices(3)
    z = {"svd": [], "lm": []}
    for seed in range(400):
        fit = fit_ellipsoid(field * readings(u, NOISE, 100 + seed), field_norm=field)
        for name in z:
            sol = getattr(fit, name)
            z[name].append(
                np.r_[
                    (sol.upper - true_upper())[upper] / sol.std_upper[upper],
                    (sol.bias - field * TRUE_BIAS) / sol.std_bias,
                ]
            )
    low, high = rms_z_band(400, 1e-4 / 18)
    for name, values in z.items():
        rms = np.sqrt(np.mean(np.square(values), axis=0))
        assert np.all((low < rms) & (rms < high)), (name, rms.round(2), low, high)


def _eq17_residuals(p: np.ndarray, m: np.ndarray) -> np.ndarray:
    """``|S'(m - o)| - 1`` for p = (6 upper entries row-major, o), written out here."""
    s = np.array([[p[0], p[1], p[2]], [0.0, p[3], p[4]], [0.0, 0.0, p[5]]])
    return np.linalg.norm((m - p[6:]) @ s.T, axis=1) - 1.0


def _gauss_newton_step_in_std(solution, m: np.ndarray) -> tuple[float, float]:
    """Sum of squared eq. 17 residuals at ``solution`` and the largest entry of the
    Gauss-Newton step from it in units of the reported std (central differences, h = 1e-6)."""
    p = np.r_[solution.upper[np.triu_indices(3)], solution.bias]
    r = _eq17_residuals(p, m)
    j = np.empty((m.shape[0], p.size))
    for k in range(p.size):
        dp = np.zeros(p.size)
        dp[k] = 1e-6
        j[:, k] = (_eq17_residuals(p + dp, m) - _eq17_residuals(p - dp, m)) / 2e-6
    step = np.linalg.lstsq(j, -r, rcond=None)[0]
    return float(r @ r), float(np.max(np.abs(step) / np.sqrt(np.diag(solution.covariance))))


@pytest.mark.parametrize("seed", [7, 8])
def test_lm_solution_is_the_minimum_of_eq17(seed):
    """At noise 0.03 the algebraic (SVD) solution is off the minimum of eq. 17 by about one
    std (its Gauss-Newton step is 1.0-1.2 std, the sum of squares ~0.002 above the minimum,
    twice the residual variance); LM must end where the gradient vanishes (a step below 1e-3
    std, seen 2e-5) with a sum of squares below the SVD's by at least one residual variance.
    A refinement stuck at its SVD start fails both."""
    u, _ = field_in_b()
    m = readings(u, 0.03, seed)
    fit = fit_ellipsoid(m)
    cost_svd, step_svd = _gauss_newton_step_in_std(fit.svd, m)
    cost_lm, step_lm = _gauss_newton_step_in_std(fit.lm, m)
    variance = cost_lm / (m.shape[0] - 9)
    assert step_svd > 0.5, step_svd
    assert step_lm < 1e-3, step_lm
    assert cost_lm < cost_svd - variance, (cost_lm, cost_svd, variance)


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


def test_sphere_coverage_counts_equal_area_cells():
    """COVERAGE_BANDS bands of equal height in z times COVERAGE_SECTORS sectors of longitude:
    one direction in the middle of every cell covers 100 %, the upper half 50 %, one cell
    1 / (bands x sectors); the directions' length does not matter."""
    from imucal.fits.magnetometer import COVERAGE_BANDS, COVERAGE_SECTORS, sphere_coverage_pct

    z = -1 + (np.arange(COVERAGE_BANDS) + 0.5) * 2 / COVERAGE_BANDS
    lon = -np.pi + (np.arange(COVERAGE_SECTORS) + 0.5) * 2 * np.pi / COVERAGE_SECTORS
    zz, ll = (a.ravel() for a in np.meshgrid(z, lon, indexing="ij"))
    u = np.column_stack([np.sqrt(1 - zz**2) * np.cos(ll), np.sqrt(1 - zz**2) * np.sin(ll), zz])
    assert sphere_coverage_pct(u) == pytest.approx(100.0)
    assert sphere_coverage_pct(7.0 * u[zz > 0]) == pytest.approx(50.0)
    assert sphere_coverage_pct(u[:1]) == pytest.approx(100.0 / (COVERAGE_BANDS * COVERAGE_SECTORS))
    # the pole z = 1 and the date line (longitude pi) fall into the last band and sector,
    # with their neighbours, not into cells beyond them
    edges = np.array(
        [
            [0.0, 0.0, 1.0],
            [np.sqrt(1 - 0.95**2), 0.0, 0.95],
            [-1.0, 0.0, 0.0],
            [-np.cos(0.01), np.sin(0.01), 0.0],
        ]
    )
    assert sphere_coverage_pct(edges) == pytest.approx(200.0 / (COVERAGE_BANDS * COVERAGE_SECTORS))


def test_ellipsoid_covariance_is_the_residual_variance_times_the_inverse_normal_matrix():
    """The docstring's covariance, sigma^2 (J^T J)^-1 with sigma^2 = r.r / (n - 9), rebuilt
    here by central differences of eq. 17, on 40 samples (where n - 9 and n + 9 differ by 2x)."""
    u, _ = field_in_b(n_phase=12, seed=3)
    m = readings(u[:40], 0.01, 9)
    fit = fit_ellipsoid(m, min_coverage_pct=5)
    for solution in (fit.svd, fit.lm):
        p = np.r_[solution.upper[np.triu_indices(3)], solution.bias]
        r = _eq17_residuals(p, m)
        j = np.empty((m.shape[0], 9))
        for k in range(9):
            dp = np.zeros(9)
            dp[k] = 1e-6
            j[:, k] = (_eq17_residuals(p + dp, m) - _eq17_residuals(p - dp, m)) / 2e-6
        want = float(r @ r) / (m.shape[0] - 9) * np.linalg.inv(j.T @ j)
        np.testing.assert_allclose(solution.covariance, want, rtol=1e-5)
        np.testing.assert_allclose(solution.std_bias, np.sqrt(np.diag(want))[6:], rtol=1e-5)
        assert solution.residual_rms == pytest.approx(np.sqrt(np.mean(r**2)), rel=1e-12)
