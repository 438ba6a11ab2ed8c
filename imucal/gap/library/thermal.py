"""Temperature: biases and scales that follow the module's temperature channel.

``temperature_drift``: its spec, the full protocol's estimator (the model term's estimators at
order 1 on the resting segments against their temperature, with the channel's warm-up curve)
and a static recording's (block means on the temperature).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from scipy.optimize import curve_fit

from imucal.columns import SENSORS, TIME, temperature_column
from imucal.gap import session as ses
from imucal.gap.effects import EffectModel, Estimate
from imucal.gap.library.registry import register
from imucal.gap.library.spec import EffectSpec
from imucal.gap.streams import Stream, temperature_blocks, temperature_slope_fits
from imucal.gap.temperature import linear_drift, select_model
from imucal.pipeline.full import SessionFit

#: Values of the recorded temperature path the twin renders where no warm-up curve describes
#: the channel (evenly spaced over the recording, each the channel's mean about its time).
PATH_VALUES = 64
#: Share of the channel's variance about its mean a warm-up curve must explain to describe it.
MIN_EXPLAINED = 0.9


@dataclass(frozen=True)
class WarmUp:
    """A warm-up curve ``start_c + rise_c (1 - exp(-t / tau_s))`` fitted to a temperature
    channel, or the reason it is not an estimate.

    Attributes
    ----------
    start_c, rise_c : float
        deg C and K (NaN where the fit failed).
    tau_s : float
        Time constant (s).
    duration_s, span_c : float
        The channel's length (s) and temperature span (K).
    refused : str
        Empty when the curve is an estimate; else why not.
    """

    start_c: float
    rise_c: float
    tau_s: float
    duration_s: float
    span_c: float
    refused: str = ""


def fit_warm_up(t_s: np.ndarray, temp_c: np.ndarray) -> WarmUp:
    """The warm-up curve of a temperature channel, refused outside physical bounds.

    A time constant beyond the recording's length ``T`` is not seen by the recording (the curve
    is then a ramp, and its rise and time constant trade against each other without bound).
    With ``tau <= T`` the recording shows at least ``1 - 1/e`` of the rise, so a rise beyond
    ``span / (1 - 1/e)`` (``span`` the channel's peak-to-peak) is beyond what the recording
    could show. A curve that leaves more than ``1 - MIN_EXPLAINED`` of the channel's variance
    about its mean does not describe the channel (a temperature cycled down and up).

    Parameters
    ----------
    t_s : ndarray, shape (n,)
        Time since the first sample (s), increasing.
    temp_c : ndarray, shape (n,)
        Temperature (deg C), finite.

    Returns
    -------
    WarmUp
    """
    duration, span = float(t_s[-1] - t_s[0]), float(np.ptp(temp_c))

    def warm(tt, start, rise, tau):
        return start + rise * (1 - np.exp(-tt / tau))

    def refused(why, start=np.nan, rise=np.nan, tau=np.nan):
        return WarmUp(float(start), float(rise), float(tau), duration, span, why)

    if not span > 0:
        return refused("the temperature channel does not change")
    try:
        (start, rise, tau), _ = curve_fit(
            warm, t_s, temp_c, p0=(temp_c[0], temp_c[-1] - temp_c[0], duration / 3),
            maxfev=4000,
        )  # fmt: skip
    except RuntimeError:
        return refused("the warm-up curve's fit did not converge")
    if not (tau > 0 and np.isfinite(rise) and np.isfinite(start)):
        return refused("the warm-up curve's fit diverged")
    bound = span / (1 - np.exp(-1))
    if tau > duration:
        why = f"time constant {tau:.3g} s beyond the recording's length {duration:.3g} s"
    elif abs(rise) > bound:
        why = (
            f"rise {rise:.3g} K beyond {bound:.3g} K, the most a curve with a time constant "
            f"within the recording can rise over its span of {span:.3g} K"
        )
    else:
        resid = temp_c - warm(t_s, start, rise, tau)
        explained = 1 - np.mean(resid**2) / np.var(temp_c)
        why = (
            f"the curve explains {100 * explained:.0f} % of the channel's variance, below "
            f"{100 * MIN_EXPLAINED:.0f} %: the channel is no warm-up"
            if explained < MIN_EXPLAINED
            else ""
        )
    return WarmUp(float(start), float(rise), float(tau), duration, span, why)


def recorded_path(t_s: np.ndarray, temp_c: np.ndarray, values: int = PATH_VALUES) -> list:
    """The channel at ``values`` evenly spaced times from 0 to its last time, each its mean
    within half a spacing of that time (deg C): the simulator's ``path_c``."""
    knots = np.linspace(0.0, float(t_s[-1]), values)
    half = 0.5 * (knots[1] - knots[0])
    out = []
    for k in knots:
        near = np.abs(t_s - k) <= half
        out.append(float(temp_c[near].mean()) if near.any() else float(np.interp(k, t_s, temp_c)))
    return out


def warm_up_params(t_s: np.ndarray, temp_c: np.ndarray) -> tuple[dict, tuple]:
    """The temperature parameters of ``temperature_drift`` for a channel, and the flags.

    The warm-up curve (:func:`fit_warm_up`) where it is an estimate: ``start_c``, ``rise_c``,
    ``tau_s``. Where it is refused, the recorded path (:func:`recorded_path`: ``start_c``,
    ``path_c``, ``path_span_s``), so the twin renders the drift on the channel as recorded,
    and a flag that says why no warm-up is reported.

    Parameters
    ----------
    t_s, temp_c : ndarray, shape (n,)
        As :func:`fit_warm_up` (time since the first sample, s; deg C).

    Returns
    -------
    params : dict
    flags : tuple of str
    """
    warm = fit_warm_up(t_s, temp_c)
    if not warm.refused:
        return {"start_c": warm.start_c, "rise_c": warm.rise_c, "tau_s": warm.tau_s}, ()
    path = recorded_path(t_s, temp_c)
    flag = (
        f"warm-up fit refused ({warm.refused}); the drift is rendered on the recorded "
        f"temperature path ({len(path)} values over {warm.duration_s:.4g} s, "
        f"{np.min(path):.2f}..{np.max(path):.2f} deg C)"
    )
    params = {"start_c": path[0], "path_c": path, "path_span_s": float(t_s[-1])}
    return params, (flag,)


def _session_channel(fit: SessionFit) -> tuple[np.ndarray, np.ndarray]:
    """The session's temperature channel on the twin's session clock (s), time-ordered;
    recordings without a channel, and samples without a reading, are left out."""
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
    order = np.argsort(ts[ok], kind="stable")
    return ts[ok][order], temps[ok][order]


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
    warm, flags = warm_up_params(*_session_channel(fit))
    vec = lambda s, k: [float(v) for v in drift[s][k]]  # noqa: E731
    params = {
        **warm,
        "acc_per_k": vec("acc", "bias"), "gyr_per_k": vec("gyr", "bias"),
        "mag_per_k": [0.0] * 3, "acc_scale_per_k": vec("acc", "scale"),
        "gyr_scale_per_k": vec("gyr", "scale"), "mag_scale_per_k": [0.0] * 3,
    }  # fmt: skip
    return Estimate(params, float(np.linalg.norm(drift["gyr"]["bias"])), flags=flags)


def estimate_static_temperature_drift(
    streams: Mapping[str, Stream], half: str | None
) -> Estimate | None:
    """Temperature path of the channel and the bias per kelvin of each axis.

    The per-axis slopes of the block means on the temperature
    (:func:`~imucal.gap.streams.temperature_slope_fits`: acc and gyro on the acc/gyro stream,
    the magnetometer on its own) are the simulator's per-axis bias drift (either sign; the
    parameterisation of the model term's polynomial at order 1), each sensor's taken where
    it predicts held-out block means better than none (:func:`slope_helps`), else 0; one
    orientation shows no scale drift (its input does not change), so the scales are 0. The
    slopes come from ``half``; the temperature path (:func:`warm_up_params`: the warm-up
    curve, or the recorded path where no warm-up is an estimate) from the whole channel, an
    input the twin carries over whole, not a parameter of the drift. Detect: the largest ``|slope| / std`` over the
    sensors and axes, taken or not (a unit-free statistic, so that a drift of the
    magnetometer alone is seen as one of the gyroscope is). Evidence: each sensor's fitted
    slopes and their std (:func:`~imucal.gap.streams.temperature_slope_fits`) and which were
    taken.
    """
    imu = streams.get("imu")
    if imu is None or imu.temperature_c is None:
        return None
    fits, taken = {}, {}
    for stream in streams.values():
        part = stream.half(half)
        fits.update(temperature_slope_fits(part))
        taken.update(slope_helps(part))
    if not fits:
        return None
    warm, flags = warm_up_params(imu.t_s - imu.t_s[0], imu.temperature_c)
    slope = {s: [float(v) for v in fits[s][0]] if taken.get(s) else [0.0] * 3 for s in SENSORS}
    ratio = [np.abs(b) / np.where(sd > 0, sd, np.inf) for b, sd in fits.values()]
    params = {
        **warm,
        "acc_per_k": slope["acc"], "gyr_per_k": slope["gyr"], "mag_per_k": slope["mag"],
        "acc_scale_per_k": [0.0] * 3, "gyr_scale_per_k": [0.0] * 3, "mag_scale_per_k": [0.0] * 3,
    }  # fmt: skip
    evidence = {f"{s}_per_k_std": [float(v) for v in sd] for s, (_, sd) in fits.items()}
    evidence |= {f"{s}_per_k_fitted": [float(v) for v in b] for s, (b, _) in fits.items()}
    evidence["taken"] = {s: bool(v) for s, v in taken.items()}
    return Estimate(params, float(np.max(ratio)), evidence=evidence, flags=flags)


def slope_helps(stream: Stream) -> dict[str, bool]:
    """Per sensor, whether a slope on the temperature predicts the stream's held-out block
    means better than none.

    The block means (:func:`~imucal.gap.streams.temperature_blocks`) with a constant per axis,
    against a constant and the temperature, each block predicted from the others
    (:func:`imucal.gap.temperature.select_model`: leave-one-out, the one-standard-error rule,
    the model term's order selection): a sensor whose slope does not predict held-out blocks
    keeps a slope of 0 in the effect.

    Returns
    -------
    dict
        Sensor -> True where the slope is taken (empty without a channel that changes).
    """
    blocks = temperature_blocks(stream)
    if blocks is None:
        return {}
    temp, means = blocks
    ones = np.ones((len(temp), 1))
    candidates = {0: ones, 1: np.column_stack([ones, temp - temp.mean()])}
    return {s: select_model(candidates, m)[0] == 1 for s, m in means.items()}


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
