"""Calibration dataclasses: dict round trip, unit checks, format version."""

from __future__ import annotations

import numpy as np
import pytest

from imucal import errormodel
from imucal.calibration import FORMAT_VERSION, ImuCalibration, SensorCalibration


def make_calibration() -> ImuCalibration:
    m = errormodel.compose([1.1, 0.9, 1.0], [0.01, -0.02, 0.005], [0.02, 0.01, -0.03])
    return ImuCalibration(
        SensorCalibration("acc", [0.1, 0.2, 0.3], m, "m/s^2", {"bias": [1e-3] * 3}, "cube"),
        SensorCalibration("gyr", [0.01, 0.02, 0.03], m, "rad/s"),
        SensorCalibration("mag", [0.1, -0.1, 0.2], m, "normalised"),
    )


def test_round_trip_through_dict():
    cal = make_calibration()
    back = ImuCalibration.from_dict(cal.to_dict())
    for s in ("acc", "gyr", "mag"):
        np.testing.assert_array_equal(back.sensor(s).matrix, cal.sensor(s).matrix)
        np.testing.assert_array_equal(back.sensor(s).bias, cal.sensor(s).bias)
    np.testing.assert_array_equal(back.acc.std["bias"], [1e-3] * 3)
    assert back.acc.method == "cube"


def test_dict_holds_decomposition():
    d = make_calibration().to_dict()
    assert d["format_version"] == FORMAT_VERSION
    np.testing.assert_allclose(d["gyr"]["scale"], [1.1, 0.9, 1.0], atol=1e-12)
    np.testing.assert_allclose(d["gyr"]["xi_rad"], [0.01, -0.02, 0.005], atol=1e-12)
    np.testing.assert_allclose(d["gyr"]["alpha_rad"], [0.02, 0.01, -0.03], atol=1e-12)


def test_newer_format_refused():
    d = make_calibration().to_dict()
    d["format_version"] = FORMAT_VERSION + 1
    with pytest.raises(ValueError, match="newer than this package"):
        ImuCalibration.from_dict(d)


def test_wrong_unit_in_file_refused():
    d = make_calibration().to_dict()
    d["gyr"]["unit_in"] = "deg/s"
    with pytest.raises(ValueError, match="'deg/s'"):
        ImuCalibration.from_dict(d)


def test_apply_refuses_wrong_unit():
    cal = make_calibration()
    with pytest.raises(ValueError, match="expects readings in 'rad/s', got 'deg/s'"):
        cal.gyr.apply(np.zeros((2, 3)), unit="deg/s")


def test_apply_calibrates():
    cal = make_calibration()
    raw = np.array([[1.0, 2.0, 3.0]])
    expected = cal.acc.matrix @ (raw[0] - cal.acc.bias)
    np.testing.assert_allclose(cal.acc.apply(raw, unit="m/s^2")[0], expected)


def test_non_finite_refused():
    with pytest.raises(ValueError, match="acc.bias must be 3 finite numbers"):
        SensorCalibration("acc", [np.nan, 0, 0], np.eye(3), "m/s^2")
