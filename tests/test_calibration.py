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


def _with_terms(rng=None):
    """The calibration of :func:`make_calibration` with every model term; with ``rng`` each
    coefficient drawn about its value with its standard deviation."""
    from imucal.modelterms import (
        GSensitivity,
        LeverArm,
        MagDelay,
        ModelTerms,
        TemperaturePolynomial,
        TemperatureTerm,
    )

    def draw(value, std):
        value, std = np.asarray(value, dtype=float), np.asarray(std, dtype=float)
        return value if rng is None else value + std * rng.standard_normal(value.shape)

    temp = {}
    for s, b, b_std in (("acc", 3e-3, 2e-4), ("gyr", 5e-4, 3e-5)):
        bias, bias_std = [[b, -b, b], [1e-5, 2e-5, -1e-5]], [[b_std] * 3, [1e-6] * 3]
        scale, scale_std = [[2e-4, 1e-4, -1e-4]], [[2e-5] * 3]
        temp[s] = TemperaturePolynomial(s, 25.0, (20.0, 30.0), 1.0, draw(bias, bias_std),
                                        draw(scale, scale_std), bias_std, scale_std)  # fmt: skip
    g_std = np.full((3, 3), 5e-6)
    r_std = np.array([2e-4, 3e-4, 1e-4])
    terms = ModelTerms(
        temperature=TemperatureTerm(temp),
        g_sensitivity=GSensitivity(draw(np.diag([2e-4, -1e-4, 1e-4]), g_std), g_std),
        lever_arm=LeverArm(draw([0.03, 0.02, 0.0], r_std), r_std),
        mag_delay=MagDelay(float(draw(0.02, 1e-3)), 1e-3),
    )
    return make_calibration().with_terms(terms)


def test_every_registered_term_round_trips_through_the_json():
    """A calibration with an example of every registered term (a new term adds its example to
    :func:`_with_terms`) is the same text after ``to_dict -> JSON -> from_dict -> to_dict``."""
    import json

    from imucal.modelterms.registry import term_names

    cal = _with_terms(np.random.default_rng(3))
    assert cal.terms.names() == list(term_names())
    text = json.dumps(cal.to_dict())
    assert json.dumps(ImuCalibration.from_dict(json.loads(text)).to_dict()) == text


def test_parameter_variance_of_the_terms_matches_their_spread():
    """Calibrating the same readings with term coefficients drawn from their standard
    deviations scatters every calibrated value as ``parameter_variance`` says (first order;
    2000 draws know a variance to ~3 %; one sensor's terms reaching another, which
    ``parameter_variance`` leaves out, are below 1 % of it here)."""
    rng = np.random.default_rng(1)
    n = 40
    t = np.arange(n) / 100.0
    # a smooth turn (the lever arm differentiates the rate) and random specific force and field
    gyr = 3.0 * np.sin(2 * np.pi * 0.5 * t[:, None] + np.array([0.0, 2.0, 4.0]))
    readings = {"acc": rng.normal(0, 9.81, (n, 3)), "gyr": gyr, "mag": rng.normal(0, 1.0, (n, 3))}
    units = {"acc": "m/s^2", "gyr": "rad/s", "mag": "normalised"}
    temp = rng.uniform(20, 30, n)
    nominal = _with_terms()
    predicted = nominal.parameter_variance(readings, temp_c=temp, t_s=t)
    draws = np.array([[v for v in _with_terms(rng).calibrate(readings, units, temp_c=temp,
                                                              t_s=t)[0].values()]
                      for _ in range(2000)])  # fmt: skip
    for i, s in enumerate(("acc", "gyr", "mag")):
        np.testing.assert_allclose(draws[:, i].var(axis=0), predicted[s], rtol=0.12)


def test_parameter_variance_is_the_covariance_without_terms():
    from imucal.uncertainty import calibrated_covariance

    cal = make_calibration()
    rng = np.random.default_rng(2)
    a = rng.normal(size=(21, 21))
    acc = ImuCalibration(
        SensorCalibration("acc", cal.acc.bias, cal.acc.matrix, "m/s^2", covariance=a @ a.T),
        cal.gyr, cal.mag,
    )  # fmt: skip
    readings = {s: rng.normal(size=(5, 3)) for s in ("acc", "gyr", "mag")}
    var = acc.parameter_variance(readings)
    assert set(var) == {"acc"}
    cov = calibrated_covariance(cal.acc.matrix, cal.acc.bias, a @ a.T, readings["acc"])
    np.testing.assert_allclose(var["acc"], np.diagonal(cov, axis1=1, axis2=2), rtol=1e-12)


def test_temperature_variance_uses_the_bias_covariance_round_trip():
    """An axis's correlated bias coefficients: the calibrated variance is ``d^T C d`` with
    ``d = (dT, dT^2)``, as the spread of calibrations with coefficients drawn from ``C``; the
    covariance survives the dict."""
    from imucal.modelterms import TemperaturePolynomial

    rng = np.random.default_rng(5)
    cov = np.array([[1e-10, -0.9e-11], [-0.9e-11, 1e-12]])  # strongly anti-correlated
    bias = np.array([[5e-4] * 3, [1e-5] * 3])
    std = np.sqrt(np.diag(cov))[:, None].repeat(3, axis=1)
    poly = TemperaturePolynomial("gyr", 25.0, (15.0, 35.0), 1.0, bias, np.zeros((0, 3)), std,
                                 np.zeros((0, 3)), bias_covariance=[cov] * 3)  # fmt: skip
    back = TemperaturePolynomial.from_dict("gyr", poly.to_dict())
    np.testing.assert_array_equal(back.bias_covariance, poly.bias_covariance)
    temp = np.linspace(15, 35, 9)
    corrected = np.ones((9, 3))
    predicted = back.variance(np.eye(3), corrected, temp)
    draws = rng.multivariate_normal(np.zeros(2), cov, size=20000)  # (draws, 2)
    d_t = temp - 25.0
    spread = (draws @ np.vstack([d_t, d_t**2])).var(axis=0)
    np.testing.assert_allclose(predicted[:, 0], spread, rtol=0.05, atol=1e-15)
    independent = np.sum((std[:, :1] * np.vstack([d_t, d_t**2])) ** 2, axis=0)
    assert np.max(independent[-1] / predicted[-1, 0]) > 3  # the correlation matters here
