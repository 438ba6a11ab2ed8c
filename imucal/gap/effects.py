"""The diagnosis's effect library: per effect an estimator of its simulator parameters from a
fitted session, its signature (the statistics it should move) and its detection statistic.

Every estimator works on physical quantities of the session (packet counter, timestamps,
rate-table run means, resting means, the temperature channel, the reference clock), never on
the simulator's internals, and returns parameters of the simulator's effect of the same name so
that the effect can be added to the twin. ``detect`` is a scalar whose null distribution comes
from running the same estimator on the twin replicas.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from imucal import errormodel
from imucal.columns import AXES, MAG, SENSOR_COLUMNS, SENSORS, SEQ, TIME
from imucal.gap import statistics as st
from imucal.gap.pipeline import SessionFit, calibrated
from imucal.sim.effects import EFFECTS, make_effect

#: Earth's rotation rate (rad/s), sidereal.
EARTH_RATE_RAD_S = 7.2921150e-5
#: Session clock gap the simulator leaves between recordings (s); the twin's clock.
SESSION_GAP_S = 60.0


@dataclass(frozen=True)
class Estimate:
    """An effect's parameters estimated from a session.

    Attributes
    ----------
    params : dict
        Parameters of the simulator effect of the same name (SI).
    detect : float
        Detection statistic (scored against the replicas' values of the same estimator).
    """

    params: dict
    detect: float


@dataclass(frozen=True)
class EffectModel:
    """One effect of the diagnosis's library.

    Attributes
    ----------
    name : str
        Canonical effect name (also the simulator effect's).
    estimate : callable
        ``(fit, half) -> Estimate or None`` (None: the session cannot show the effect).
    signature : tuple of (stage, sensor, statistic)
        Locations the effect should move (``'*'`` matches any sensor).
    description : str
    """

    name: str
    estimate: Callable
    signature: tuple
    description: str

    def simulator_effect(self, params: dict):
        return make_effect(self.name, **params)

    def matches(self, key: tuple) -> bool:
        return any(
            key[0] == stage and sensor in ("*", key[1]) and key[4] == stat
            for stage, sensor, stat in self.signature
        )


def _halves(fit: SessionFit, half):
    return {name: t.iloc[st._time_half(len(t), half)] for name, t in fit.imu.items()}


def estimate_packet_loss(fit: SessionFit, half) -> Estimate:
    lost = expected = 0
    gaps = []
    for t in _halves(fit, half).values():
        n, e, g = st.lost_packets(t[SEQ].to_numpy())
        lost, expected = lost + n, expected + e
        gaps.append(g)
    g = np.concatenate(gaps)
    fraction = lost / max(expected, 1)
    burst = float(g.mean()) if len(g) else 1.0
    params = {"fraction": float(fraction), "model": "bernoulli", "burst_mean": 1.0}
    if burst > 1.2:
        burst_cap = max(burst, fraction * 1.01 / max(1 - fraction, 1e-9))
        params.update(model="gilbert", burst_mean=float(burst_cap))
    return Estimate(params, float(fraction))


def estimate_timing_jitter(fit: SessionFit, half) -> Estimate:
    res = []
    for t in _halves(fit, half).values():
        r = st.stamp_residual(t[TIME].to_numpy(dtype=float), t[SEQ].to_numpy())
        res.append(r - np.median(r))
    r = np.concatenate(res)
    std = float(np.std(r))
    return Estimate({"std_s": std}, std)


def estimate_time_offset(fit: SessionFit, half) -> Estimate | None:
    if fit.time_alignment is None:
        return None
    stats = st._reference(fit, half)
    offset = stats[("validate", "clock", "-", "rotation3d", "ref_offset_s")]
    drift = float(fit.time_alignment.drift_ppm)
    return Estimate({"offset_s": float(offset), "drift_ppm": drift}, abs(float(offset)))


def estimate_lever_arm(fit: SessionFit, half) -> Estimate | None:
    if fit.artifacts.get("table") is None:
        return None
    r = -st.centripetal_slopes(fit, half)
    r = np.nan_to_num(r)
    return Estimate({"x_m": float(r[0]), "y_m": float(r[1]), "z_m": float(r[2])}, float(np.linalg.norm(r)))


def estimate_g_sensitivity(fit: SessionFit, half) -> Estimate:
    w, f = st.resting_gyro(fit, half)
    design = np.column_stack([np.ones(len(f)), f])
    coef, *_ = np.linalg.lstsq(design, w, rcond=None)
    g_b = coef[1:].T  # rows: gyro axis, columns: specific-force axis
    k_mat = fit.calibration.sensor("gyr").matrix
    k = np.diag(np.linalg.solve(k_mat, g_b))
    return Estimate({"kx": float(k[0]), "ky": float(k[1]), "kz": float(k[2])}, float(np.linalg.norm(k)))


def estimate_earth_rotation(fit: SessionFit, half) -> Estimate:
    w, f = st.resting_gyro(fit, half)
    up = f / np.linalg.norm(f, axis=1, keepdims=True)
    a_mat = np.vstack(
        [np.column_stack([np.eye(3)[j][None].repeat(len(w), 0), up[:, j]]) for j in range(3)]
    )
    coef, *_ = np.linalg.lstsq(a_mat, w.T.ravel(), rcond=None)
    vertical = float(coef[3])
    resid = w - coef[:3] - vertical * up
    perp = resid - np.sum(resid * up, axis=1, keepdims=True) * up
    noise_var = _position_mean_variance(fit, half)
    h2 = max(float(np.mean(np.sum(perp**2, axis=1))) - 2 * noise_var, 0.0)
    horizontal = np.sqrt(h2)
    rate = float(np.hypot(vertical, horizontal))
    lat = float(np.degrees(np.arctan2(vertical, horizontal))) if rate > 0 else 0.0
    return Estimate({"latitude_deg": lat, "rate_rad_s": max(rate, 1e-12)}, vertical)


def _position_mean_variance(fit: SessionFit, half) -> float:
    """Mean variance (rad/s)^2 of one axis of a calibrated gyro position mean (white noise)."""
    rows = st._alternate(st._rows(fit, "cube", "position"), half)
    gyr = calibrated(fit, "cube", "gyr")
    v = []
    for r in rows.itertuples(index=False):
        x = gyr[int(r.start_index) : int(r.end_index)]
        d = np.diff(x, axis=0)
        v.append(np.mean(np.var(d, axis=0) / 2) / len(x))
    return float(np.mean(v))


def estimate_saturation(fit: SessionFit, half) -> Estimate:
    opt = fit.extra["options"]
    params, detect = {}, 0.0
    stats = st._clipping(fit, half)
    for s in SENSORS:
        frac = stats[("ingest", s, "-", "all", "clip_fraction")]
        top = 32767
        if frac > 0:
            peak = max(
                np.nanmax(np.abs(t[list(SENSOR_COLUMNS[s])].to_numpy(dtype=float)))
                for t in fit.imu.values()
            )
            top = int(np.clip(round(peak / float(opt.sensitivity[s])), 1, 32767))
        params[s] = top
        detect = max(detect, frac)
    return Estimate(params, detect)


def _session_clock(fit: SessionFit) -> dict:
    """Start of each recording on the twin's session clock (s)."""
    starts, t = {}, 0.0
    for name in ("rotation3d", "cube", "ratetable", "static"):
        if name in fit.imu:
            starts[name] = t
            tt = fit.imu[name][TIME].to_numpy(dtype=float)
            t += tt[-1] - tt[0] + SESSION_GAP_S
    return starts


def estimate_temperature_drift(fit: SessionFit, half) -> Estimate | None:
    from scipy.optimize import curve_fit

    col = next((st.temperature_column(t) for t in fit.imu.values() if st.temperature_column(t)), None)
    if col is None or "static" not in fit.imu:
        return None
    starts = _session_clock(fit)
    ts, temps = [], []
    for name, start in starts.items():
        t = fit.imu[name][TIME].to_numpy(dtype=float)
        ts.append(start + t - t[0])
        temps.append(fit.imu[name][col].to_numpy(dtype=float))
    ts, temps = np.concatenate(ts), np.concatenate(temps)
    if np.ptp(temps) <= 0:
        return None

    def warm(t, start, rise, tau):
        return start + rise * (1 - np.exp(-t / tau))

    try:
        (start, rise, tau), _ = curve_fit(
            warm, ts, temps, p0=(temps[0], np.ptp(temps), ts[-1] / 2), maxfev=2000
        )
        if not (tau > 0 and np.isfinite(rise)):
            raise RuntimeError
    except RuntimeError:
        start, rise, tau = temps[0], np.ptp(temps) * 1e3, ts[-1] * 1e3
    static = fit.imu["static"].iloc[st._time_half(len(fit.imu["static"]), half)]
    temp = static[col].to_numpy(dtype=float)
    coef = {}
    for s in ("acc", "gyr"):
        x = static[list(SENSOR_COLUMNS[s])].to_numpy(dtype=float)
        tc = temp - temp.mean()
        if tc @ tc <= 0:
            return None
        slopes = tc @ (x - x.mean(axis=0)) / (tc @ tc)
        coef[s] = float(np.median(slopes))
    params = {
        "start_c": float(start), "rise_c": float(rise), "tau_s": float(tau),
        "acc_per_k": coef["acc"], "gyr_per_k": coef["gyr"], "mag_per_k": 0.0,
        "acc_scale_per_k": 0.0, "gyr_scale_per_k": 0.0, "mag_scale_per_k": 0.0,
    }  # fmt: skip
    return Estimate(params, abs(coef["gyr"]))


def estimate_bias_instability(fit: SessionFit, half) -> Estimate | None:
    if "static" not in fit.imu:
        return None
    table = fit.imu["static"].iloc[st._time_half(len(fit.imu["static"]), half)]
    t = table[TIME].to_numpy(dtype=float)
    fs = 1 / np.median(np.diff(t))
    params, detect = {}, 0.0
    for s in ("acc", "gyr"):
        x = table[list(SENSOR_COLUMNS[s])].to_numpy(dtype=float)
        white = np.std(np.diff(x, axis=0), axis=0) / np.sqrt(2)
        tau = min(100.0, (t[-1] - t[0]) / 5)
        m = max(int(tau * fs), 1)
        ad = st.allan_deviation(x, m)
        excess = np.maximum(ad**2 - white**2 / m, 0.0)
        gm = float(np.sqrt(np.mean(excess))) / 0.62
        params.update({f"{s}_gm": gm, f"{s}_rw": 0.0, f"{s}_tau_s": 100.0})
        if s == "gyr":
            detect = gm
    params.update(mag_gm=0.0, mag_rw=0.0, mag_tau_s=100.0)
    return Estimate(params, detect)


def estimate_scale_nonlinearity(fit: SessionFit, half) -> Estimate | None:
    if fit.artifacts.get("table") is None:
        return None
    opt = fit.extra["options"]
    fs = 32767 * float(opt.sensitivity["gyr"])
    rows, res, true = st.table_residuals(fit, half)
    scale = errormodel.decompose(fit.calibration.sensor("gyr").matrix).scale
    k2, k3 = [], []
    for j, a in enumerate(AXES):
        sel = (rows["axis"] == a).to_numpy()
        w, y = true[sel, j], res[sel, j]
        if len(w) < 4:
            continue
        c, *_ = np.linalg.lstsq(np.column_stack([np.ones_like(w), w, w**2, w**3]), y, rcond=None)
        k2.append(c[2] * scale[j] * fs)
        k3.append(c[3] * scale[j] ** 2 * fs**2)
    if not k2:
        return None
    g2, g3 = float(np.mean(k2)), float(np.mean(k3))
    params = {"gyr_k2": g2, "gyr_k3": g3, "acc_k2": 0.0, "acc_k3": 0.0, "mag_k2": 0.0, "mag_k3": 0.0}
    return Estimate(params, float(np.hypot(g2, g3)))


def estimate_mag_latency(fit: SessionFit, half) -> Estimate:
    lags = [st.magnetometer_lag(fit, p) for p in st._phase_half(AXES, half)]
    lag = float(np.nanmean(lags))
    mag = fit.imu["rotation3d"][list(MAG)].to_numpy(dtype=float)
    fresh = mag[np.all(np.isfinite(mag), axis=1)]
    repeats = float(np.mean(np.all(np.diff(fresh, axis=0) == 0, axis=1))) if len(fresh) > 1 else 0.0
    packet_mag_hz = 10.0
    rate = packet_mag_hz * (1 - repeats) if repeats > 0.05 else 75.0
    delay = max(lag - 1 / (2 * rate), 0.0)
    return Estimate({"rate_hz": float(rate), "delay_s": float(delay)}, lag)


_LIBRARY = (
    EffectModel("packet_loss", estimate_packet_loss,
                (("ingest", "clock", "loss_fraction"),),
                "radio packets lost: gaps in the packet counter"),
    EffectModel("timing_jitter", estimate_timing_jitter,
                (("ingest", "clock", "stamp_scatter_s"),),
                "irregular receive timestamps about the packet clock"),
    EffectModel("time_offset", estimate_time_offset,
                (("validate", "clock", "ref_offset_s"), ("validate", "clock", "ref_drift_ppm")),
                "offset and drift of the reference clock against the module"),
    EffectModel("lever_arm", estimate_lever_arm,
                (("acc_table", "acc", "omega2"),),
                "module off the rotation axis: acc run means grow with rate^2"),
    EffectModel("g_sensitivity", estimate_g_sensitivity,
                (("gyr_static", "gyr", "g_slope"), ("gyr_static", "gyr", "spread"),
                 ("gyr_static", "gyr", "vertical"), ("gyr_table", "gyr", "resid_rms")),
                "gyro output proportional to specific force at rest"),
    EffectModel("earth_rotation", estimate_earth_rotation,
                (("gyr_static", "gyr", "vertical"), ("gyr_static", "gyr", "spread")),
                "Earth's rate in the resting gyro means, along the vertical and across it"),
    EffectModel("saturation", estimate_saturation,
                (("ingest", "*", "clip_fraction"), ("gyr_table", "gyr", "left_out")),
                "samples clipped at the sensor range"),
    EffectModel("temperature_drift", estimate_temperature_drift,
                (("temperature", "*", "temp_slope"), ("noise", "*", "trend_per_s"),
                 ("noise", "*", "adev_long_excess")),
                "biases following the temperature channel"),
    EffectModel("bias_instability", estimate_bias_instability,
                (("noise", "*", "adev_long_excess"), ("noise", "*", "adev_10s_excess"),
                 ("noise", "*", "trend_per_s"), ("gyr_static", "gyr", "spread")),
                "wandering biases: Allan deviation above the white-noise line at long tau"),
    EffectModel("scale_nonlinearity", estimate_scale_nonlinearity,
                (("gyr_table", "gyr", "rate2"), ("gyr_table", "gyr", "rate3"),
                 ("gyr_table", "gyr", "resid_rms"), ("gyr_scale", "gyr", "scale_ratio")),
                "rate-table residuals curved in the rate"),
    EffectModel("mag_latency", estimate_mag_latency,
                (("mag", "mag", "lag_s"),),
                "magnetometer lagging the gyroscope during rotations"),
)  # fmt: skip

#: Effect name -> model, for the effects the simulator has.
LIBRARY = {m.name: m for m in _LIBRARY if m.name in EFFECTS}


def library(exclude: tuple = ()) -> dict:
    """The library without the effects named in ``exclude`` (the unknown-effect check)."""
    unknown = sorted(set(exclude) - set(LIBRARY))
    if unknown:
        raise ValueError(f"cannot exclude {unknown}: not in the library {sorted(LIBRARY)}")
    return {k: v for k, v in LIBRARY.items() if k not in exclude}
