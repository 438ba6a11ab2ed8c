"""Temperature: biases and scales that follow the module's temperature channel.

``temperature_drift``: its spec, the full protocol's estimator (the model term's estimators at
order 1 on the resting segments against their temperature, with the channel's warm-up curve)
and a static recording's (block means on the temperature).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from scipy.optimize import curve_fit

from imucal.columns import TIME, temperature_column
from imucal.gap import session as ses
from imucal.gap.effects import EffectModel, Estimate
from imucal.gap.library.registry import register
from imucal.gap.library.spec import EffectSpec
from imucal.gap.streams import Stream, temperature_slopes
from imucal.gap.temperature import linear_drift
from imucal.pipeline.full import SessionFit


def _warm_up(fit: SessionFit) -> tuple[float, float, float]:
    """Start, rise (deg C) and time constant (s) of the session's temperature channel, fitted
    with the simulator's warm-up curve on the twin's session clock (recordings without a
    channel, and samples without a reading, are left out)."""
    ts, temps = [], []
    for name, start in ses.session_clock(fit).items():
        col = temperature_column(fit.imu[name])
        if col is None:
            continue
        t = fit.imu[name][TIME].to_numpy(dtype=float)
        ts.append(start + t - t[0])
        temps.append(fit.imu[name][col].to_numpy(dtype=float))
    ts, temps = np.concatenate(ts), np.concatenate(temps)
    ok = np.isfinite(temps)
    ts, temps = ts[ok], temps[ok]

    def warm(t, start, rise, tau):
        return start + rise * (1 - np.exp(-t / tau))

    try:
        (start, rise, tau), _ = curve_fit(
            warm, ts, temps, p0=(temps[0], np.ptp(temps), ts[-1] / 2), maxfev=2000
        )
        if tau > 0 and np.isfinite(rise):
            return float(start), float(rise), float(tau)
    except RuntimeError:
        pass
    return float(temps[0]), float(np.ptp(temps) * 1e3), float(ts[-1] * 1e3)  # a slow ramp


def estimate_temperature_drift(fit: SessionFit, half) -> Estimate | None:
    """Drift per kelvin of each axis, either sign, from the resting segments of the whole
    session against their temperature: the model term's estimators at order 1
    (:func:`imucal.gap.temperature.linear_drift`: gyro bias from the raw resting means with
    a constant and the calibrated specific force in the same regression, so that a
    g-sensitivity is not taken for a drift; gyro scale from the rate-table runs; accelerometer
    bias and scale from ``|a| - g``), with the warm-up curve of the temperature channel.
    Detection: the norm of the gyro bias drift over the axes (rad/s/K). None without a
    temperature channel or with fewer than 6 resting segments that have a reading."""
    if not any(temperature_column(t) for t in fit.imu.values()):
        return None
    drift = linear_drift(fit, half)
    if drift is None:
        return None
    start, rise, tau = _warm_up(fit)
    vec = lambda s, k: [float(v) for v in drift[s][k]]  # noqa: E731
    params = {
        "start_c": start, "rise_c": rise, "tau_s": tau,
        "acc_per_k": vec("acc", "bias"), "gyr_per_k": vec("gyr", "bias"),
        "mag_per_k": [0.0] * 3, "acc_scale_per_k": vec("acc", "scale"),
        "gyr_scale_per_k": vec("gyr", "scale"), "mag_scale_per_k": [0.0] * 3,
    }  # fmt: skip
    return Estimate(params, float(np.linalg.norm(drift["gyr"]["bias"])))


def estimate_static_temperature_drift(
    streams: Mapping[str, Stream], half: str | None
) -> Estimate | None:
    """Warm-up curve of the temperature channel and the bias per kelvin of each axis.

    The per-axis slopes of the block means on the temperature
    (:func:`~imucal.gap.streams.temperature_slopes`) are the simulator's per-axis bias drift
    (either sign; the parameterisation of the model term's polynomial at order 1); one
    orientation shows no scale drift (its input does not change), so the scales are 0.
    Detect: the largest |gyro slope| over the axes (rad/s/K).
    """
    imu = streams.get("imu")
    if imu is None:
        return None
    imu = imu.half(half)
    slopes = temperature_slopes(imu)
    if not slopes:
        return None
    t = imu.t_s - imu.t_s[0]
    temp = imu.temperature_c

    def warm(tt, start, rise, tau):
        return start + rise * (1 - np.exp(-tt / tau))

    try:
        (start, rise, tau), _ = curve_fit(
            warm, t, temp, p0=(temp[0], temp[-1] - temp[0], t[-1] / 3), maxfev=4000
        )
        if not (tau > 0 and np.isfinite(rise)):
            raise RuntimeError("warm-up fit diverged")
    except RuntimeError:
        # a straight line: the exponential with a time constant far beyond the recording
        slope = np.polyfit(t, temp, 1)
        tau = 1e3 * t[-1]
        start, rise = slope[1], slope[0] * tau
    params = {
        "start_c": float(start), "rise_c": float(rise), "tau_s": float(tau),
        "acc_per_k": [float(v) for v in slopes.get("acc", np.zeros(3))],
        "gyr_per_k": [float(v) for v in slopes.get("gyr", np.zeros(3))],
        "mag_per_k": [0.0] * 3, "acc_scale_per_k": [0.0] * 3, "gyr_scale_per_k": [0.0] * 3,
        "mag_scale_per_k": [0.0] * 3,
    }  # fmt: skip
    return Estimate(params, float(np.max(np.abs(slopes.get("gyr", np.zeros(3))))))


#: The statistics a drift with temperature moves (the full protocol's and a static recording's).
_DRIFT_SIGNATURE = (
    ("temperature", "*", "temp_slope"),
    ("noise", "*", "trend_per_s"),
    ("noise", "*", "adev_long_excess"),
)
_DRIFT_SEEN = "biases following the temperature channel"

TEMPERATURE_DRIFT = register(EffectSpec(
    name="temperature_drift",
    description="the module warms up over the session; biases and scales drift per axis",
    kind="systematic",
    scopes={
        "protocol": EffectModel("temperature_drift", estimate_temperature_drift,
                                _DRIFT_SIGNATURE, _DRIFT_SEEN),
        "static": EffectModel("temperature_drift", estimate_static_temperature_drift,
                              _DRIFT_SIGNATURE, _DRIFT_SEEN),
        "motion": "no static recording with a temperature channel",
        "rests": "the temperature hardly changes within a rest of a few seconds, and the levels "
        "of different rests differ by their orientation",
        "field_fit": "no temperature channel in a magnetometer's tumble",
    },
))  # fmt: skip
