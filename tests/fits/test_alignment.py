"""T_R from the rotation3d phases (eqs. 25-31): recovery of a known rotation, identifiability."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from imucal import errormodel
from imucal.columns import MAG, TIME
from imucal.fits.alignment import align_constant_component, align_rotation_axis, phase_samples

ALPHA = np.radians([3.0, -2.0, 4.0])  # several degrees: the small-angle form must show its error
NOISE = 0.004  # per axis, as the conformance magnetometer


def circle_phases(
    t_r: np.ndarray, constants=(0.3, -0.45, -0.85), n: int = 150, noise: float = 0.0, seed: int = 0
) -> dict[str, np.ndarray]:
    """Step-1 output v' = T_R^T u of a unit vector turning twice about each axis of B."""
    rng = np.random.default_rng(seed)
    out = {}
    for a, (label, c) in enumerate(zip("xyz", constants)):
        phi = np.linspace(0, 4 * np.pi, n, endpoint=False) + a
        b, d = (k for k in range(3) if k != a)
        u = np.zeros((n, 3))
        u[:, a] = c
        u[:, b] = np.sqrt(1 - c * c) * np.cos(phi)
        u[:, d] = np.sqrt(1 - c * c) * np.sin(phi)
        out[label] = u @ t_r + rng.normal(0, noise, u.shape)  # rows: T_R^T u
    return out


def rate_phases(t_r: np.ndarray, n: int = 300, noise: float = 0.0, seed: int = 0):
    """Gyro step-1 output w' = T_R^T (rate e_a) with a ramp-up, plateau and ramp-down of rate."""
    rng = np.random.default_rng(seed)
    profile = np.radians(50.0) * np.clip(np.minimum(np.arange(n), n - np.arange(n)) / 30, 0, 1)
    out = {}
    for a, label in enumerate("xyz"):
        w = np.zeros((n, 3))
        w[:, a] = profile * (1 if a != 1 else -1)
        out[label] = w @ t_r + rng.normal(0, noise, w.shape)
    return out


@pytest.mark.parametrize("method", ["full", "paper"])
def test_constant_component_recovers_exact_rotation_without_noise(method):
    t_r = errormodel.rotation_matrix(ALPHA)
    res = align_constant_component(circle_phases(t_r), method=method)
    # noise-free data and an exact model: only round-off remains
    np.testing.assert_allclose(res.alpha_rad, ALPHA, atol=1e-9)
    np.testing.assert_allclose(res.apply(circle_phases(t_r)["x"])[:, 0], 0.3, atol=1e-9)


def test_small_angle_form_degrades_for_several_degrees():
    t_r = errormodel.rotation_matrix(ALPHA)
    exact = align_constant_component(circle_phases(t_r), exact=True)
    small = align_constant_component(circle_phases(t_r), exact=False)
    err_exact = np.abs(exact.matrix - t_r).max()
    err_small = np.abs(small.matrix - t_r).max()
    assert err_exact < 1e-9
    # I + [alpha]x misses the second-order terms, |alpha|^2 / 2 ~ 2e-3 for these angles
    assert err_small > 0.25 * np.dot(ALPHA, ALPHA) / 2


@pytest.mark.parametrize("method", ["full", "paper"])
def test_constant_component_with_noise(method):
    t_r = errormodel.rotation_matrix(ALPHA)
    phases = circle_phases(t_r, noise=NOISE, seed=3)
    res = align_constant_component(phases, method=method)
    # full: each phase fixes two angles from n samples on a circle of radius rho >= 0.5, so
    # sigma_angle ~ NOISE / (rho sqrt(n / 2)) ~ 9e-4 rad; paper: 2 chords of length ~2 rho,
    # sigma ~ NOISE / rho ~ 8e-3 rad. Tolerance 5 sigma; the reported std must agree.
    tol = 5 * NOISE / 0.5 * (np.sqrt(2 / 150) if method == "full" else 1.0)
    np.testing.assert_allclose(res.alpha_rad, ALPHA, atol=tol)
    assert np.all(np.abs(res.alpha_rad - ALPHA) < 5 * res.std_alpha_rad + 1e-12)
    assert np.all(res.std_alpha_rad < tol)
    if method == "full":
        # the constant component's spread is the axial noise after alignment
        for spread in res.spread.values():
            assert spread == pytest.approx(NOISE, rel=0.2)  # 150 samples: std of std ~ 6 %


def test_two_phases_identify_the_rotation_and_one_does_not():
    t_r = errormodel.rotation_matrix(ALPHA)
    phases = circle_phases(t_r)
    for pair in (("x", "y"), ("y", "z"), ("x", "z")):
        res = align_constant_component({k: phases[k] for k in pair})
        np.testing.assert_allclose(res.alpha_rad, ALPHA, atol=1e-9)
    with pytest.raises(ValueError, match="rotation about x is not identifiable"):
        align_constant_component({"x": phases["x"]})


def test_accelerometer_z_phase_is_skipped():
    t_r = errormodel.rotation_matrix(ALPHA)
    # gravity: the x and y axes horizontal (constant 0), in phase z gravity stays on z
    phases = circle_phases(t_r, constants=(0.0, 0.0, 0.0), noise=0.01, seed=5)
    phases = {k: 9.81 * v for k, v in phases.items() if k != "z"}
    rng = np.random.default_rng(6)
    phases["z"] = np.tile([0.0, 0.0, 9.81], (150, 1)) @ t_r + rng.normal(0, 0.05, (150, 3))
    res = align_constant_component(phases)
    assert set(res.skipped) == {"z"} and "sweep" in res.skipped["z"]
    assert set(res.used_points) == {"x", "y"}
    # noise 0.0981 m/s^2 on a circle of radius 9.81: 5 * 0.01 * sqrt(2/150) rad
    np.testing.assert_allclose(res.alpha_rad, ALPHA, atol=5 * 0.01 * np.sqrt(2 / 150))
    with pytest.raises(ValueError, match="no usable phase"):
        align_constant_component({"z": phases["z"]})


def test_paper_uses_the_extreme_points():
    t_r = errormodel.rotation_matrix(ALPHA)
    phases = circle_phases(t_r)
    res = align_constant_component(phases, method="paper")
    idx = res.used_points["x"]
    assert idx.shape == (4,)
    v = phases["x"]
    assert idx[0] == v[:, 1].argmax() and idx[3] == v[:, 2].argmin()


@pytest.mark.parametrize("method", ["full", "paper"])
def test_rotation_axis_recovers_exact_rotation(method):
    t_r = errormodel.rotation_matrix(ALPHA)
    res = align_rotation_axis(rate_phases(t_r), method=method)
    np.testing.assert_allclose(res.alpha_rad, ALPHA, atol=1e-9)
    if method == "paper":
        assert res.used_points["y"].tolist() == [100, 200]
    small = align_rotation_axis(rate_phases(t_r), method=method, exact=False)
    assert np.abs(small.matrix - t_r).max() > 0.25 * np.dot(ALPHA, ALPHA) / 2


def test_rotation_axis_with_noise_and_a_still_phase():
    t_r = errormodel.rotation_matrix(ALPHA)
    noise = np.radians(0.5)  # rad/s per axis
    phases = rate_phases(t_r, noise=noise, seed=9)
    phases["z"] = np.random.default_rng(1).normal(0, noise, (300, 3))  # platform did not turn
    res = align_rotation_axis(phases)
    assert set(res.skipped) == {"z"}
    # two off-axis rows per phase over ~270 samples at ~0.87 rad/s: sigma ~ noise/(0.87 sqrt(270))
    tol = 5 * noise / (0.87 * np.sqrt(270))
    np.testing.assert_allclose(res.alpha_rad, ALPHA, atol=tol)


def test_bad_input_is_refused():
    t_r = errormodel.rotation_matrix(ALPHA)
    phases = circle_phases(t_r)
    with pytest.raises(ValueError, match="unknown alignment method 'best'"):
        align_constant_component(phases, method="best")
    with pytest.raises(ValueError, match="unknown phase label 'w'"):
        align_constant_component({"w": phases["x"], **phases})
    bad = phases["y"].copy()
    bad[7] = np.nan
    with pytest.raises(ValueError, match="phase 'y': 1 samples are not finite, first at index 7"):
        align_constant_component({**phases, "y": bad})


def test_phase_samples_cuts_the_segments():
    n = 100
    table = pd.DataFrame(
        {TIME: np.arange(n) * 0.01, MAG[0]: np.arange(n, dtype=float), MAG[1]: 0.0, MAG[2]: 0.0}
    )
    table.loc[table.index % 10 != 0, list(MAG)] = np.nan
    segments = pd.DataFrame(
        {
            "recording": ["rotation3d", "rotation3d", "cube"],
            "label": ["x", "y", "p01"],
            "kind": ["phase", "phase", "position"],
            "start_index": [5, 40, 0],
            "end_index": [35, 80, 10],
        }
    )
    out = phase_samples(table, segments, "mag")
    assert sorted(out) == ["x", "y"]
    np.testing.assert_array_equal(out["x"][1][:, 0], [10.0, 20.0, 30.0])
    np.testing.assert_allclose(out["y"][0], [0.4, 0.5, 0.6, 0.7])
    segments.loc[1, "end_index"] = 101
    with pytest.raises(ValueError, match=r"phase 'y' of 'rotation3d' spans rows \[40, 101\)"):
        phase_samples(table, segments, "mag")
