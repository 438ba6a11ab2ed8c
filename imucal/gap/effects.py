"""The diagnosis's effect library: per effect an estimator of its simulator parameters from a
fitted session, its signature (the statistics it should move) and its detection statistic.

Every estimator works on physical quantities of the session (packet counter, timestamps,
rate-table run means, resting means, the temperature channel, the reference clock), never on
the simulator's internals, and returns parameters of the simulator's effect of the same name so
that the effect can be added to the twin. ``detect`` is a scalar whose null distribution comes
from running the same estimator on the twin replicas.

The library holds one estimator per effect of the simulator, each beside the signature it is
matched by, so that an effect is defined in one place.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from imucal import errormodel
from imucal.columns import (
    AXES,
    MAG,
    SENSOR_COLUMNS,
    SENSORS,
    SEQ,
    TIME,
    column_values,
    temperature_column,
)
from imucal.constants import EARTH_RATE_RAD_S
from imucal.gap import locations as loc
from imucal.gap import session as ses
from imucal.gap.temperature import linear_drift
from imucal.pipeline.full import SessionFit, calibrated
from imucal.sim.effects import EFFECTS, make_effect


@dataclass(frozen=True)
class Estimate:
    """An effect's parameters estimated from a session.

    Attributes
    ----------
    params : dict
        Parameters of the simulator effect of the same name (SI).
    detect : float
        Detection statistic (scored against the replicas' values of the same estimator).
    evidence : dict
        Values the effect's physics gate reads beside the parameters (not simulator
        parameters), e.g. the magnetometer's lag in each phase.
    """

    params: dict
    detect: float
    evidence: dict = field(default_factory=dict)


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
    return {name: t.iloc[ses.time_half(len(t), half)] for name, t in fit.imu.items()}


def estimate_packet_loss(fit: SessionFit, half) -> Estimate:
    lost = expected = 0
    gaps = []
    for t in _halves(fit, half).values():
        n, e, g = loc.lost_packets(t[SEQ].to_numpy())
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
        r = loc.stamp_residual(t[TIME].to_numpy(dtype=float), t[SEQ].to_numpy())
        res.append(r - np.median(r))
    r = np.concatenate(res)
    std = float(np.std(r))
    return Estimate({"std_s": std}, std)


def estimate_time_offset(fit: SessionFit, half) -> Estimate | None:
    if fit.time_alignment is None:
        return None
    stats = loc.reference_clock_locations(fit, half)
    offset = stats[("validate", "clock", "-", "rotation3d", "ref_offset_s")]
    drift = float(fit.time_alignment.drift_ppm)
    return Estimate({"offset_s": float(offset), "drift_ppm": drift}, abs(float(offset)))


def estimate_lever_arm(fit: SessionFit, half) -> Estimate | None:
    if fit.artifacts["gyr_table"] is None:
        return None
    r = -loc.centripetal_slopes(fit, half)
    r = np.nan_to_num(r)
    return Estimate(
        {"x_m": float(r[0]), "y_m": float(r[1]), "z_m": float(r[2])}, float(np.linalg.norm(r))
    )


def estimate_g_sensitivity(fit: SessionFit, half) -> Estimate | None:
    """The full matrix ``G`` of ``w_B = c + G a_B`` (rad/s per m/s^2, frame B: the model
    term's and the simulator's parameterisation) from the calibrated resting means of the
    session (:func:`imucal.gap.session.resting_means`), each gyro axis regressed on the
    three components of the specific force with a constant, as
    :func:`imucal.terms.gsensitivity.fit_g_sensitivity`; with a temperature channel the
    temperature is in the same regression (a per-axis drift over poses taken at different
    temperatures is not taken for a g-sensitivity). Detection: ``|G|`` (Frobenius). None when
    the resting segments do not span three directions of gravity."""
    rest = ses.resting_means(fit, half)
    w, f = rest.gyr, rest.acc
    columns = [np.ones(len(w)), *f.T]
    if np.any(np.isfinite(rest.temp)) and np.nanmax(rest.temp) > np.nanmin(rest.temp):
        columns.append(np.nan_to_num(rest.temp - np.nanmean(rest.temp)))
    design = np.column_stack(columns)
    ok = np.all(np.isfinite(w), axis=1) & np.all(np.isfinite(design), axis=1)
    design, w = design[ok], w[ok]
    if len(w) <= design.shape[1] + 1 or np.linalg.matrix_rank(design[:, :4]) < 4:
        return None
    coef, *_ = np.linalg.lstsq(design, w, rcond=None)
    g = coef[1:4].T  # rows: gyro axis, columns: specific-force axis
    return Estimate({"matrix": g.tolist()}, float(np.linalg.norm(g)))


def estimate_earth_rotation(fit: SessionFit, half) -> Estimate | None:
    """Latitude and rate of the world-fixed rate that the resting segments share
    (:func:`imucal.gap.locations.world_fixed_rate`: north from the magnetometer, up from the
    accelerometer); detection: its magnitude."""
    omega = loc.world_fixed_rate(fit, half)
    if omega is None:
        return None
    rate = float(np.linalg.norm(omega))
    lat = float(np.degrees(np.arctan2(omega[2], np.hypot(omega[0], omega[1])))) if rate > 0 else 0.0
    return Estimate({"latitude_deg": lat, "rate_rad_s": max(rate, 1e-12)}, rate)


def _null_std(null: list, get) -> float:
    vals = np.array([get(e) for e in null if e is not None], dtype=float)
    return float(np.std(vals, ddof=1)) if len(vals) > 2 else float("inf")


def earth_gate(est: Estimate, null: list, z: float) -> str:
    """The Earth's rate is known: a world-fixed rate beyond ``EARTH_RATE_RAD_S`` by more than
    ``z`` null standard deviations of the estimator is not the Earth."""
    s_r = _null_std(null, lambda e: e.params["rate_rad_s"])
    rate = est.params["rate_rad_s"]
    if rate > EARTH_RATE_RAD_S + z * s_r:
        return (f"world-fixed rate {rate:.3g} rad/s exceeds the Earth's {EARTH_RATE_RAD_S:.4g} "
                f"rad/s by > {z:g} null std ({s_r:.2g})")  # fmt: skip
    return ""


def latency_gate(est: Estimate, null: list, z: float) -> str:
    """A latency delays the magnetometer alike in every rotation: the phases' lags
    (``evidence['lag_s']``) must agree with one delay within the null's spread of each
    (replicas, prediction interval). Their weighted scatter about the common delay is a
    chi-square on ``k - 1`` degrees of freedom, read against the F distribution of the null's
    ``n - 1`` (its spread is estimated) at the two-sided tail of ``z``. A field that moves with
    the platform (or any error of the calibrated field) bends the phases' angles in ways of
    their own: lags of either sign, which one delay does not explain."""
    from scipy import stats as sps

    lags = np.asarray(est.evidence.get("lag_s", ()), dtype=float)
    rows = [e.evidence.get("lag_s") for e in null if e is not None]
    rows = [r for r in rows if r is not None and len(r) == len(lags)]
    if len(lags) < 2 or len(rows) < 3:
        return ""
    null_lags = np.asarray(rows, dtype=float)
    n = np.sum(np.isfinite(null_lags), axis=0)
    spread = np.nanstd(null_lags, axis=0, ddof=1) * np.sqrt(1 + 1 / np.maximum(n, 1))
    ok = np.isfinite(lags) & np.isfinite(spread) & (spread > 0) & (n >= 3)
    if ok.sum() < 2:
        return ""
    w = 1 / spread[ok] ** 2
    delay = float(np.sum(w * lags[ok]) / np.sum(w))
    chi2 = float(np.sum(w * (lags[ok] - delay) ** 2))
    dof = int(ok.sum()) - 1
    p = float(sps.f.sf(chi2 / dof, dof, int(n[ok].min()) - 1))
    if p < 2 * sps.norm.sf(z):
        shown = ", ".join(f"{a} {x:+.3f}" for a, x in zip(AXES, lags, strict=False))
        return (f"the phases' lags ({shown} s) disagree with one delay: chi-square "
                f"{chi2:.3g} on {dof} dof against the null's spread (p = {p:.1g})")  # fmt: skip
    return ""


def estimate_saturation(fit: SessionFit, half) -> Estimate:
    opt = fit.extra["options"]
    params, detect = {}, 0.0
    stats = loc.clipping_locations(fit, half)
    for s in SENSORS:
        frac = stats[("ingest", s, "-", "all", "clip_fraction")]
        top = 32767
        if frac > 0:
            peak = max(
                np.nanmax(np.abs(column_values(t, SENSOR_COLUMNS[s]))) for t in fit.imu.values()
            )
            top = int(np.clip(round(peak / float(opt.sensitivity[s])), 1, 32767))
        params[s] = top
        detect = max(detect, frac)
    return Estimate(params, detect)


def _warm_up(fit: SessionFit) -> tuple[float, float, float]:
    """Start, rise (deg C) and time constant (s) of the session's temperature channel, fitted
    with the simulator's warm-up curve on the twin's session clock (recordings without a
    channel, and samples without a reading, are left out)."""
    from scipy.optimize import curve_fit

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


#: Correlation time (s) assumed for the Gauss-Markov part when converting the variance seen
#: over a short recording to its stationary std (typical MEMS, effects.md #3; the recording
#: is too short to estimate it).
BIAS_TAU_S = 100.0


def _wander_variance(
    t: np.ndarray, y: np.ndarray, var: np.ndarray, design: np.ndarray, tau_s: float
) -> tuple[float, float, float]:
    """Gauss-Markov variance of a bias from its means, by the variogram of the residuals after
    the regressors are taken out, and the variogram's excess over white noise with its
    variance under white noise alone.

    With ``M = I - X X^+`` (``X`` the design), the residuals ``r = M y`` of means with white
    noise ``D = diag(var)`` and a wander of covariance ``gm^2 C``, ``C_ij = exp(-|t_i - t_j| /
    tau)``, have ``E[(r_i - r_j)^2] = d^T M (D + gm^2 C) M d`` with ``d = e_i - e_j``: linear in
    ``gm^2``, solved by least squares over all pairs (may be negative under noise alone). The
    estimate is ``(r^T Q r - tr(Q S)) / sum b^2`` with ``Q`` the pairs' weighted Laplacian
    (weights ``b``, the pairs' wander coefficients) and ``S = M D M``; under white noise alone
    the excess ``r^T Q r - tr(Q S)`` has mean 0 and variance ``2 tr(Q S Q S)``.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Segment times (s).
    y : ndarray, shape (n,)
        Segment means (SI).
    var : ndarray, shape (n,)
        White-noise variance of each mean (SI^2).
    design : ndarray, shape (n, p)
        Regressors taken out first (a constant, temperature, specific force, ...).
    tau_s : float
        Correlation time (s).

    Returns
    -------
    gm2 : float
        ``gm^2`` (SI^2).
    excess, excess_var : float
        ``r^T Q r - tr(Q S)`` (SI^4) and its variance under white noise (SI^8).
    """
    m = np.eye(len(t)) - design @ np.linalg.pinv(design)
    r = m @ y
    noise = m @ np.diag(var) @ m
    wander = m @ np.exp(-np.abs(t[:, None] - t[None, :]) / tau_s) @ m
    diag = np.diag(wander)
    b = diag[:, None] + diag[None, :] - 2 * wander
    np.fill_diagonal(b, 0.0)
    q = np.diag(b.sum(axis=1)) - b  # sum over pairs of b_ij (e_i - e_j)(e_i - e_j)^T
    qs = q @ noise
    excess = float(r @ q @ r - np.trace(qs))
    return excess / float(np.sum(np.triu(b, 1) ** 2)), excess, float(2 * np.sum(qs * qs.T))


#: Level of the test that decides whether the gyro's resting means show a g-sensitivity
#: (:func:`_shows_g_sensitivity`): only then are the specific force's columns taken out of the
#: wander's regression (each costs power: the poses are grouped in time).
G_TEST_P = 1e-3


def _shows_g_sensitivity(rest: ses.RestingMeans, base: np.ndarray) -> bool:
    """Whether the gyro's resting means depend on the specific force beyond their white noise:
    per axis the weighted least squares of the mean on ``base`` and the three specific-force
    components, and the chi-square of the nine specific-force coefficients against their
    covariance, at level :data:`G_TEST_P`. A wander between poses makes the coefficients
    noisier than the white noise says and can only make the test say yes (the conservative
    side: the columns are then taken out, as with a g-sensitivity)."""
    from scipy import stats as sps

    design = np.column_stack([base, rest.acc])
    p = base.shape[1]
    if len(rest) <= design.shape[1] + 2 or np.linalg.matrix_rank(design) < design.shape[1]:
        return True
    chi2 = 0.0
    for k in range(3):
        w = 1 / rest.gyr_var[:, k]
        info = design.T @ (design * w[:, None])
        coef = np.linalg.solve(info, design.T @ (w * rest.gyr[:, k]))
        cov = np.linalg.inv(info)[p:, p:]
        chi2 += float(coef[p:] @ np.linalg.solve(cov, coef[p:]))
    return chi2 > sps.chi2.isf(G_TEST_P, 9)


def _table_runs(fit: SessionFit, half) -> dict | None:
    """The rate-table's turning runs kept by its fit, as wander samples of the gyro bias.

    Returns
    -------
    dict or None
        ``t`` (r,) session time (s); ``res`` (r, 3) run-mean residuals of the table's vector
        fit (rad/s); ``var`` (r, 3) their white-noise variances; ``rate`` (r, 3) the table's
        rate vector (rad/s); ``acc`` (r, 3) calibrated specific force; ``temp`` (r,) mean
        temperature (NaN without a channel). None without a table fit or turning runs.
    """
    if fit.artifacts["gyr_table"] is None or "ratetable" not in fit.imu:
        return None
    rows, res, rate = ses.table_residuals(fit, half)
    turning = (rows["rate_dps"] != 0).to_numpy()
    if turning.sum() < 4:
        return None
    rows, res, rate = rows[turning], res[turning], rate[turning]
    table = fit.imu["ratetable"]
    gyr, acc = calibrated(fit, "ratetable", "gyr"), calibrated(fit, "ratetable", "acc")
    col = temperature_column(table)
    temp = table[col].to_numpy(dtype=float) if col else None
    q = float(fit.extra["options"].sensitivity["gyr"]) ** 2 / 12
    var, acc_mean, temps = [], [], []
    for start, end in ses.row_bounds(rows):
        w = gyr[start:end][np.all(np.isfinite(gyr[start:end]), axis=1)]
        a = acc[start:end][np.all(np.isfinite(acc[start:end]), axis=1)]
        var.append(ses.white_variance(w, q) if len(w) > 2 else np.full(3, np.nan))
        acc_mean.append(a.mean(axis=0) if len(a) else np.full(3, np.nan))
        seg = temp[start:end] if temp is not None else np.array([np.nan])
        temps.append(float(np.nanmean(seg)) if np.any(np.isfinite(seg)) else np.nan)
    mid = 0.5 * (rows["start_s"].to_numpy(float) + rows["end_s"].to_numpy(float))
    t = ses.session_clock(fit)["ratetable"] + mid - float(table[TIME].iloc[0])
    return {"t": t, "res": res, "var": np.array(var), "rate": rate,
            "acc": np.array(acc_mean), "temp": np.array(temps)}  # fmt: skip


def _centred(temp: np.ndarray) -> np.ndarray:
    """Temperature about its mean, 0 where there is no reading (a zero column when none has)."""
    if not np.any(np.isfinite(temp)):
        return np.zeros(len(temp))
    return np.nan_to_num(temp - np.nanmean(temp))


def estimate_bias_instability(fit: SessionFit, half) -> Estimate | None:
    """Gauss-Markov bias std of the gyroscope (per axis, averaged) and the accelerometer (along
    gravity, from ``|a| - g``) from the variogram (:func:`_wander_variance`) of the resting
    means (:func:`imucal.gap.session.resting_means`) and, for the gyroscope, the run means of
    the rate table's turning runs, on the twin's session clock.

    The wander is the bias's change with time; what else moves these means is taken out
    first, so that it is not counted as wander:

    * resting means: a constant, a line in the temperature (where a segment has no reading,
      none) and, for the gyro, the specific force when the means show a g-sensitivity
      (:func:`_shows_g_sensitivity`; the Earth's vertical rate goes with it then);
    * turning runs (residuals of the table's vector fit, which already took out the bias and
      the scale and misalignment matrix): their own constant, the rate vector and, per axis,
      its square and cube (a scale non-linearity), its product with the temperature (a
      scale drift) and the temperature, and the specific force when the rests show a
      g-sensitivity (each mounting then has its own ``G g``).

    The runs fill the middle of a platform session, where the rests are few (the table's
    rest runs). The Earth's rate is left in (taking out a world-fixed rate per axis costs
    more power than it adds on MEMS-class means). The correlation time is taken as
    ``BIAS_TAU_S`` (a session of minutes cannot resolve it) and the random walk as 0.
    Detection: the gyroscope's variogram excess over white noise, summed over the axes, over
    its standard deviation under white noise alone (:func:`_wander_variance`): comparable
    between a session whose specific force is taken out and its replicas, which show no
    g-sensitivity (the accelerometer's, seen through ``|a| - g`` after the cube fit, is much
    the noisier). None with fewer than 4 resting segments.
    """
    rest = ses.resting_means(fit, half)
    n = len(rest)
    if n < 4:
        return None
    clock = ses.session_clock(fit)
    t = np.array([clock[rec] for rec in rest.recording]) + rest.mid_s
    d_t = _centred(rest.temp)
    base = np.column_stack([np.ones(n), d_t]) if np.ptp(d_t) > 0 else np.ones((n, 1))
    g = fit.extra["options"].gravity_m_s2
    gm2_acc, *_ = _wander_variance(
        t, np.linalg.norm(rest.acc, axis=1) - g, rest.acc_var, base, BIAS_TAU_S
    )
    with_sf = n > base.shape[1] + 6 and _shows_g_sensitivity(rest, base)
    design = np.column_stack([base, rest.acc]) if with_sf else base
    runs = _table_runs(fit, half)
    if runs is not None:
        ok = np.all(np.isfinite(runs["var"]), axis=1) & np.all(np.isfinite(runs["acc"]), axis=1)
        runs = {k: v[ok] for k, v in runs.items()}
        if len(runs["t"]) < 4:
            runs = None
    gm2_gyr, excess, excess_var = [], 0.0, 0.0
    for k in range(3):
        y, var, times, x = rest.gyr[:, k], rest.gyr_var[:, k], t, design
        if runs is not None:
            w = runs["rate"][:, k]
            d_tr = _centred(runs["temp"])
            cols = [np.ones(len(w)), *runs["rate"].T, w**2, w**3]
            if np.ptp(d_tr) > 0:
                cols += [d_tr, w * d_tr]
            if with_sf:
                cols += list(runs["acc"].T)
            xr = np.column_stack(cols)
            x = np.block([[x, np.zeros((len(x), xr.shape[1]))],
                          [np.zeros((len(xr), x.shape[1])), xr]])  # fmt: skip
            y = np.concatenate([y, runs["res"][:, k]])
            var = np.concatenate([var, runs["var"][:, k]])
            times = np.concatenate([t, runs["t"]])
        gm2_k, ex_k, var_k = _wander_variance(times, y, var, x, BIAS_TAU_S)
        gm2_gyr.append(gm2_k)
        excess, excess_var = excess + ex_k, excess_var + var_k
    gm2 = float(np.mean(gm2_gyr))
    params = {
        "acc_gm": float(np.sqrt(max(gm2_acc, 0.0))), "acc_rw": 0.0, "acc_tau_s": BIAS_TAU_S,
        "gyr_gm": float(np.sqrt(max(gm2, 0.0))), "gyr_rw": 0.0, "gyr_tau_s": BIAS_TAU_S,
        "mag_gm": 0.0, "mag_rw": 0.0, "mag_tau_s": BIAS_TAU_S,
    }  # fmt: skip
    return Estimate(params, excess / np.sqrt(excess_var) if excess_var > 0 else 0.0)


def estimate_scale_nonlinearity(fit: SessionFit, half) -> Estimate | None:
    if fit.artifacts["gyr_table"] is None:
        return None
    opt = fit.extra["options"]
    fs = 32767 * float(opt.sensitivity["gyr"])
    rows, res, true = ses.table_residuals(fit, half)
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
    params = {
        "gyr_k2": g2,
        "gyr_k3": g3,
        "acc_k2": 0.0,
        "acc_k3": 0.0,
        "mag_k2": 0.0,
        "mag_k3": 0.0,
    }
    return Estimate(params, float(np.hypot(g2, g3)))


def estimate_mag_latency(fit: SessionFit, half) -> Estimate:
    """Delay of the magnetometer from the mean of the phases' lags, less the sample-and-hold's
    half period; the phases' lags are the evidence of :func:`latency_gate`."""
    lags = [loc.magnetometer_lag(fit, p) for p in ses.phase_half(AXES, half)]
    lag = float(np.nanmean(lags))
    mag = column_values(fit.imu["rotation3d"], MAG)
    fresh = mag[np.all(np.isfinite(mag), axis=1)]
    repeats = float(np.mean(np.all(np.diff(fresh, axis=0) == 0, axis=1))) if len(fresh) > 1 else 0.0
    packet_mag_hz = 10.0
    rate = packet_mag_hz * (1 - repeats) if repeats > 0.05 else 75.0
    delay = max(lag - 1 / (2 * rate), 0.0)
    return Estimate(
        {"rate_hz": float(rate), "delay_s": float(delay)}, lag, {"lag_s": [float(x) for x in lags]}
    )


def estimate_platform_magnetic(fit: SessionFit, half) -> Estimate | None:
    """Platform-fixed field from the resting poses' world field against the outer-axis angle
    (:func:`imucal.gap.locations.platform_field`) and the motor-current term from the
    field residual against the angular acceleration during the motion."""
    pf = loc.platform_field(fit, half)
    if pf is None:
        return None
    d_h, m_earth = pf
    rot, psi = loc.platform_motion(fit)
    t = fit.imu["rotation3d"][TIME].to_numpy(dtype=float)
    mag = calibrated(fit, "rotation3d", "mag")
    low = column_values(fit.lowpass, SENSOR_COLUMNS["gyr"])
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
    """Placement std per axis (deg) from the cube positions' tilts that the accelerometer
    and the magnetometer see together, and the rate-table mountings' tilts (their rest runs).

    A placement error is a rigid rotation of the cube: it turns gravity and the field together
    in B. The accelerometer's tilts alone (:func:`imucal.gap.locations.cube_direction_residuals`)
    are also made by an accelerometer bias or temperature drift, which leaves the field where
    it was. So the cube's std is the covariance of the two sensors' tilts about the axis that
    changes the angle between them (:func:`imucal.gap.locations.cube_joint_tilts`):
    ``sigma^2 = sum(a f) / sum(1 - h_ii)``, at least 0; the error and noise of either sensor
    alone add nothing to it on average. None for a cube held by hand (its poses are the hand's,
    and the session has no direction statistic) or with a field at fewer than five nominal
    positions.

    Returns
    -------
    Estimate or None
        ``cube_sigma_deg``, ``table_sigma_deg`` (deg, std per axis); detection: the cube's.
    """
    if "cube" in fit.extra["options"].held_by_hand:
        return None
    acc, field, free = loc.cube_joint_tilts(fit, half)
    if not len(free):
        return None
    cube = float(np.degrees(np.sqrt(max(np.sum(acc * field) / np.sum(free), 0.0))))
    tilts = loc.table_mount_tilts(fit)
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
                (("gyr_static", "gyr", "world_rate"), ("gyr_static", "gyr", "vertical"),
                 ("gyr_static", "gyr", "spread")),
                "Earth's rate in the resting gyro means: a rate fixed in the world (north, up)",
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
                "magnetometer lagging the gyroscope during rotations", gate=latency_gate),
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
