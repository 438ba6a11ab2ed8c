"""Physical bounds of fitted calibrations and the comparison with their fallback."""

from __future__ import annotations

import numpy as np

from imucal import errormodel
from imucal.fits.magnetometer import fit_ellipsoid
from imucal.validation.plausibility import (
    BOUNDS,
    check_bounds,
    compare_with_fallback,
)


def test_every_sensor_has_documented_bounds():
    for sensor, bounds in BOUNDS.items():
        assert bounds.scale[0] < 1.0 < bounds.scale[1] and bounds.nonorthogonality_deg > 0
        assert "datasheet" in bounds.source, sensor


def test_ellipsoid_of_the_low_coverage_recording_is_implausible():
    # the shipped magnetometer of a 20 % coverage recording: scales 1.41 / 1.19 / 0.83 and
    # non-orthogonality -12.8 / -4.1 / 9.4 deg, with the small std of a confident fit
    matrix = errormodel.compose([1.41, 1.19, 0.83], np.radians([-12.8, -4.1, 9.4]), np.zeros(3))
    out = check_bounds("mag", matrix, np.full((3, 3), 0.01))
    text = " ".join(out["implausible"])
    assert "relative scale x = 1.26" in text and "relative scale z = 0.743" in text
    assert "xi_x (deg) = -12.8" in text and "xi_z (deg) = 9.4" in text
    assert len(out["implausible"]) == 4  # xi_y = -4.1 deg is within 5 deg


def test_plausible_and_undetermined_gyroscopes():
    matrix = errormodel.compose([1.02, 0.99, 1.01], np.radians([0.3, -0.5, 0.2]), np.zeros(3))
    assert check_bounds("gyr", matrix, np.full((3, 3), 0.002)) == {
        "implausible": [],
        "undetermined": [],
    }
    # scale 1.27 with std 0.01: outside [0.8, 1.25] by 2 std, not confidently
    off = errormodel.compose([1.27, 1.0, 1.0], np.zeros(3), np.zeros(3))
    out = check_bounds("gyr", off, np.full((3, 3), 0.01))
    assert out["implausible"] == [] and "scale x = 1.27" in out["undetermined"][0]
    # the paper's module, 13-15 % below its nominal sensitivity, is within the bounds
    paper = errormodel.compose([1.1526, 1.1327, 1.1425], np.radians([0.35, -0.65, 0.54]), [0, 0, 0])
    assert check_bounds("gyr", paper, np.full((3, 3), 1e-4))["implausible"] == []
    # an interval wider than the plausible range says nothing either
    out = check_bounds("gyr", np.eye(3), np.diag([0.001, 0.001, 0.1]))
    assert len(out["undetermined"]) == 1 and "scale z" in out["undetermined"][0]


def test_thin_band_ellipsoid_is_at_least_warned():
    # hand turns about one axis with small tilts (+-6 deg): the axis across the band is not
    # determined; the fit is refused, or its z scale warned about
    rng = np.random.default_rng(0)
    phi, z = rng.uniform(0, 1.5 * np.pi, 3000), rng.uniform(-0.1, 0.1, 3000)
    r = np.sqrt(1 - z**2)
    m = np.column_stack([r * np.cos(phi), r * np.sin(phi), z]) / [1.05, 0.97, 1.0]
    m = m + [0.3, -0.2, 0.1] + rng.normal(0, 0.02, m.shape)
    from imucal import uncertainty

    fit = fit_ellipsoid(m)
    cov = uncertainty.step1_only_covariance(fit.upper, fit.bias, fit.selected.covariance)
    out = check_bounds("mag", fit.upper, uncertainty.std_of(cov)["matrix"])
    assert out["implausible"] or any("relative scale z" in w for w in out["undetermined"])


def test_fitted_worse_than_fallback():
    starts = np.arange(10.0)
    fitted = [{"10s": (starts, np.full(10, 2.0))}]
    fallback = [{"10s": (starts, np.full(10, 1.0))}]
    assert compare_with_fallback(fitted, fallback)["worse"] is True
    assert compare_with_fallback(fallback, fitted)["worse"] is False
    assert compare_with_fallback([{"10s": (starts[:0], starts[:0])}], fallback)["worse"] is None


def test_full_protocol_stages_warn_instead_of_refusing():
    from imucal.calibration import SensorCalibration
    from imucal.validation.plausibility import bound_warnings

    matrix = errormodel.compose([1.41, 1.19, 0.83], np.zeros(3), np.zeros(3))
    cal = SensorCalibration("mag", np.zeros(3), matrix, "normalised").to_dict()
    out = bound_warnings("mag_step2", "mag", cal)
    assert len(out) == 2 and all(w.startswith("mag_step2: mag relative scale") for w in out)
    assert all("implausible, but shipped" in w for w in out)
    assert bound_warnings("mag_step2", "mag", {**cal, "matrix": np.eye(3).tolist()}) == []


def test_review_refuses_on_weak_data_and_warns_on_strong():
    from imucal.calibration import SensorCalibration
    from imucal.validation.plausibility import review_fit

    ellipsoid = errormodel.compose([1.41, 1.19, 0.83], np.radians([-12.8, -4.1, 9.4]), [0, 0, 0])
    cal = SensorCalibration("mag", np.zeros(3), ellipsoid, "normalised").to_dict()
    # at 20 % of the sphere: refused, each implausible value named with the coverage
    weak = review_fit("mag", cal, {"coverage_pct": 20.0})
    assert len(weak["refuse"]) == 4 and weak["warn"] == []
    assert weak["refuse"][0].endswith("on 20 % of the sphere (below 50 % the ellipsoid's axes "
                                      "trade off against each other)")  # fmt: skip
    # the same on 99 % of the sphere: the data determine it, shipped with warnings
    strong = review_fit("mag", cal, {"coverage_pct": 99.0})
    assert strong["refuse"] == [] and len(strong["warn"]) == 4
    # a gyroscope 31 % above a nominal sensitivity that was assumed: a warning to check it
    gyr = SensorCalibration("gyr", np.zeros(3), np.diag([1.311, 1.313, 1.308]), "rad/s").to_dict()
    out = review_fit("gyr", gyr, {})
    assert out["refuse"] == [] and "check the declared units and sensitivity" in out["warn"][0]
