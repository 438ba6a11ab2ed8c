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
    gate : callable, optional
        Physics check ``(estimate, null_estimates, z) -> str``: the reason the estimate cannot
        be this effect (empty when it can), with the null estimates (replicas) giving the
        estimator's spread and ``z`` the detection threshold.
    opens_gap : bool
        False for an effect the pipeline's exact model absorbs (reported, never attributed).
    """

    name: str
    estimate: Callable
    signature: tuple
    description: str
    gate: Callable | None = None
    opens_gap: bool = True

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


def _null_std(null: list, get) -> float:
    vals = np.array([get(e) for e in null if e is not None], dtype=float)
    return float(np.std(vals, ddof=1)) if len(vals) > 2 else float("inf")


def earth_gate(est: Estimate, null: list, z: float) -> str:
    """The Earth's rate is known: a vertical component or a rate beyond ``EARTH_RATE_RAD_S``
    by more than ``z`` null standard deviations of the estimator is not the Earth."""
    s_v = _null_std(null, lambda e: e.detect)
    s_r = _null_std(null, lambda e: e.params["rate_rad_s"])
    if abs(est.detect) > EARTH_RATE_RAD_S + z * s_v:
        return (f"vertical rate {est.detect:.3g} rad/s exceeds the Earth's "
                f"{EARTH_RATE_RAD_S:.4g} rad/s by > {z:g} null std ({s_v:.2g})")  # fmt: skip
    rate = est.params["rate_rad_s"]
    if rate > EARTH_RATE_RAD_S + z * s_r:
        return (f"rate {rate:.3g} rad/s exceeds the Earth's {EARTH_RATE_RAD_S:.4g} rad/s "
                f"by > {z:g} null std ({s_r:.2g})")  # fmt: skip
    return ""


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


#: Block length (s) of the static recording's bias-variation statistic.
BIAS_BLOCK_S = 10.0
#: Correlation time (s) assumed for the Gauss-Markov part when converting the variance seen
#: over a short recording to its stationary std (typical MEMS, effects.md #3; the recording
#: is too short to estimate it).
BIAS_TAU_S = 100.0


def _visible_fraction(span_s: float, tau_s: float) -> float:
    """Expected sample variance over a window ``span_s`` of a Gauss-Markov process of
    correlation time ``tau_s``, as a fraction of its stationary variance."""
    r = tau_s / span_s
    return float(1 - 2 * r + 2 * r**2 * (1 - np.exp(-1 / r)))


def bias_block_excess(fit: SessionFit, half) -> dict | None:
    """Variance of block means of the static recording beyond white noise, per sensor.

    The static recording is cut into blocks of ``BIAS_BLOCK_S``; per axis the variance of the
    block means over the white-noise prediction (``sigma^2 / L`` with ``sigma`` from first
    differences) is 1 for white noise. A temperature channel with a range is regressed out
    first, so a drift that follows the temperature does not count as bias instability.

    Returns
    -------
    dict or None
        Sensor ('acc', 'gyr') -> (ratio - 1 per axis, shape (3,); excess variance of the block
        means per axis (SI^2), shape (3,)); with key 'span_s'. None without a static recording
        of at least 4 blocks.
    """
    if "static" not in fit.imu:
        return None
    table = fit.imu["static"].iloc[st._time_half(len(fit.imu["static"]), half)]
    t = table[TIME].to_numpy(dtype=float)
    if len(t) < 2:
        return None
    length = max(int(round(BIAS_BLOCK_S / np.median(np.diff(t)))), 2)
    n_blocks = len(t) // length
    if n_blocks < 4:
        return None
    col = st.temperature_column(table)
    temp = table[col].to_numpy(dtype=float) if col else None
    out = {"span_s": float(t[-1] - t[0])}
    for s in ("acc", "gyr"):
        x = table[list(SENSOR_COLUMNS[s])].to_numpy(dtype=float)
        white2 = np.var(np.diff(x, axis=0), axis=0) / 2
        blocks = x[: n_blocks * length].reshape(n_blocks, length, 3).mean(axis=1)
        if temp is not None and np.ptp(temp) > 0:
            tb = temp[: n_blocks * length].reshape(n_blocks, length).mean(axis=1)
            design = np.column_stack([np.ones(n_blocks), tb - tb.mean()])
            coef, *_ = np.linalg.lstsq(design, blocks, rcond=None)
            blocks = blocks - design @ coef
            dof = n_blocks - 2
        else:
            blocks = blocks - blocks.mean(axis=0)
            dof = n_blocks - 1
        var = np.sum(blocks**2, axis=0) / dof
        out[s] = (var / (white2 / length) - 1, np.maximum(var - white2 / length, 0.0))
    return out


def estimate_bias_instability(fit: SessionFit, half) -> Estimate | None:
    """Gauss-Markov bias std per sensor from the static block-mean excess; detection pooled
    over the 6 acc and gyro axes (mean of the variance ratios minus 1)."""
    ex = bias_block_excess(fit, half)
    if ex is None:
        return None
    frac = max(_visible_fraction(ex["span_s"], BIAS_TAU_S), 1e-3)
    params = {}
    for s in ("acc", "gyr"):
        gm = float(np.sqrt(np.mean(ex[s][1]) / frac))
        params.update({f"{s}_gm": gm, f"{s}_rw": 0.0, f"{s}_tau_s": BIAS_TAU_S})
    params.update(mag_gm=0.0, mag_rw=0.0, mag_tau_s=BIAS_TAU_S)
    detect = float(np.mean(np.concatenate([ex["acc"][0], ex["gyr"][0]])))
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


def estimate_platform_magnetic(fit: SessionFit, half) -> Estimate | None:
    """Platform-fixed field from the resting poses' world field against the outer-axis angle
    (:func:`imucal.gap.statistics.platform_field`) and the motor-current term from the
    field residual against the angular acceleration during the motion."""
    pf = st.platform_field(fit, half)
    if pf is None:
        return None
    d_h, m_earth = pf
    rot, psi = st.platform_motion(fit)
    t = fit.imu["rotation3d"][TIME].to_numpy(dtype=float)
    mag = calibrated(fit, "rotation3d", "mag")
    low = fit.lowpass[list(SENSOR_COLUMNS["gyr"])].to_numpy(dtype=float)
    cal = fit.calibration.sensor("gyr")
    w_dot = np.gradient(cal.apply(low, unit=cal.unit), t, axis=0)
    d = np.array([d_h[0], d_h[1], 0.0])
    c, sn = np.cos(psi), np.sin(psi)
    d_world = np.column_stack([c * d[0] - sn * d[1], sn * d[0] + c * d[1], np.zeros_like(c)])
    pred = rot.apply(m_earth + d_world, inverse=True)
    ok = np.all(np.isfinite(mag), axis=1) & np.all(np.isfinite(w_dot), axis=1)
    r, wd = (mag - pred)[ok], w_dot[ok]
    current = float(np.sum(r * wd) / np.sum(wd * wd)) if np.sum(wd * wd) > 0 else 0.0
    params = {"field_x": float(d[0]), "field_y": float(d[1]), "field_z": 0.0,
              "current_per_rad_s2": current}  # fmt: skip
    return Estimate(params, float(np.linalg.norm(d_h)))


def estimate_placement_error(fit: SessionFit, half) -> Estimate | None:
    """Placement std per axis (deg) from the cube positions' tilts about their nominal
    directions (2 tilt components per position, 3 dof of the common rotation; white noise of
    the position means removed) and the rate-table mountings' tilts (their rest runs)."""
    res, noise, _ = st.cube_direction_residuals(fit, half)
    if len(res) < 3:
        return None
    dof = 2 * len(res) - 3
    var = max((np.sum(res**2) - 2 * np.sum(noise)) / dof, 0.0)
    cube = float(np.degrees(np.sqrt(var)))
    tilts = st.table_mount_tilts(fit)
    table = float(np.degrees(np.sqrt(np.sum(tilts**2) / (2 * len(tilts))))) if len(tilts) else cube
    return Estimate({"cube_sigma_deg": cube, "table_sigma_deg": table}, cube)


def estimate_large_misalignment(fit: SessionFit, half) -> Estimate:
    """Misalignment angle |alpha| (deg) of each sensor of the fitted calibration (exact
    rotation); detection: the largest."""
    params = {
        f"{s}_deg": float(np.degrees(np.linalg.norm(
            errormodel.decompose(fit.calibration.sensor(s).matrix).alpha_rad)))
        for s in SENSORS
    }  # fmt: skip
    return Estimate(params, max(params.values()))


def _relative_matrix(k: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """``k ref^-1 - I``: the relative error of a calibration matrix against another."""
    return k @ np.linalg.inv(ref) - np.eye(3)


def misalignment_report(fit: SessionFit, replica_fits: list, z: float) -> dict:
    """Whether the paper's small-angle form (eq. 5) would open a gap for this calibration.

    The session's alignment stages are refitted with the small-angle form
    (:func:`imucal.gap.pipeline.refit_alignment`); the small-angle matrix error of a sensor is
    the Frobenius norm of ``K_small K_exact^-1 - I``. Its precision is the matrix's own: the
    root of the summed variances of the entries of ``K_r Kbar^-1 - I`` over the replicas
    (null; their truths carry the session's fitted angles). A sensor needs the exact rotation
    when the small-angle error exceeds ``z`` times that precision. The replicas' own
    small-angle errors are given as the twin's reproduction of the session's.

    Returns
    -------
    dict
        Per sensor ``angles_deg`` (fitted ``|alpha|``), ``small_angle_error`` (session),
        ``replica_small_angle_error`` (mean, std over the replicas), ``matrix_precision``;
        ``sensors`` where the small-angle form would fail; ``present`` and a ``note``.
    """
    from imucal.gap.pipeline import refit_alignment

    angles = estimate_large_misalignment(fit, None).params
    small = refit_alignment(fit, exact=False)
    rep_small = [refit_alignment(f, exact=False) for f in replica_fits]
    out = {"angles_deg": {}, "small_angle_error": {}, "replica_small_angle_error": {},
           "matrix_precision": {}, "z": float(z), "sensors": []}  # fmt: skip
    for s in SENSORS:
        k = fit.calibration.sensor(s).matrix
        err = float(np.linalg.norm(_relative_matrix(small.sensor(s).matrix, k)))
        ks = np.array([f.calibration.sensor(s).matrix for f in replica_fits])
        prec = float("inf")
        if len(ks) > 2:
            rel = np.array([_relative_matrix(x, ks.mean(axis=0)) for x in ks])
            prec = float(np.sqrt(np.sum(np.var(rel, axis=0, ddof=1))))
        rep = np.array([
            np.linalg.norm(_relative_matrix(r.sensor(s).matrix, f.calibration.sensor(s).matrix))
            for r, f in zip(rep_small, replica_fits, strict=True)
        ])  # fmt: skip
        out["angles_deg"][s] = angles[f"{s}_deg"]
        out["small_angle_error"][s] = err
        out["replica_small_angle_error"][s] = (
            [float(rep.mean()), float(rep.std(ddof=1))] if len(rep) > 1 else None
        )
        out["matrix_precision"][s] = prec
        if err > z * prec:
            out["sensors"].append(s)
    out["present"] = bool(out["sensors"])
    if out["present"]:
        worst = ", ".join(f"{s} {out['angles_deg'][s]:.1f} deg (small-angle matrix error "
                          f"{out['small_angle_error'][s]:.1e} vs precision "
                          f"{out['matrix_precision'][s]:.1e})" for s in out["sensors"])  # fmt: skip
        out["note"] = (f"large misalignment: {worst}. The exact rotation used here absorbs it "
                       "(no gap from it); the paper's small-angle variant (exact_rotation: "
                       f"false) would change the matrix by more than {z:g} times its "
                       "precision.")  # fmt: skip
    else:
        out["note"] = ("misalignment angles small enough for the small-angle form: its matrix "
                       f"error is within {z:g} times the matrix precision")  # fmt: skip
    return out


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
                "Earth's rate in the resting gyro means, along the vertical and across it",
                gate=earth_gate),
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
    EffectModel("platform_magnetic", estimate_platform_magnetic,
                (("mag", "mag", "platform_field"), ("mag", "mag", "norm_spread"),
                 ("mag", "mag", "resid_rms"), ("mag", "mag", "dip_spread_rad")),
                "a field turning with the platform's outer axis: |m| and the world field "
                "change between resting poses at different platform angles"),
    EffectModel("placement_error", estimate_placement_error,
                (("acc_cube", "acc", "dir_resid_rad"),),
                "cube / table poses tilted from their nominal directions while |a| fits"),
    EffectModel("large_misalignment", estimate_large_misalignment, (),
                "misalignment of several degrees: absorbed by the exact rotation, a gap only "
                "with the small-angle variant", opens_gap=False),
)  # fmt: skip

#: Effect name -> model, for the effects the simulator has.
LIBRARY = {m.name: m for m in _LIBRARY if m.name in EFFECTS}


def library(exclude: tuple = ()) -> dict:
    """The library without the effects named in ``exclude`` (the unknown-effect check)."""
    unknown = sorted(set(exclude) - set(LIBRARY))
    if unknown:
        raise ValueError(f"cannot exclude {unknown}: not in the library {sorted(LIBRARY)}")
    return {k: v for k, v in LIBRARY.items() if k not in exclude}
