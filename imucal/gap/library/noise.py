"""A wandering bias: the noise beyond white that the twin of the full protocol does not draw.

``bias_instability``: its spec, the full protocol's estimator (the variogram of the resting
means and the rate table's run means on the twin's session clock, with what else moves them
taken out first) and a static recording's (the Allan excess at long averaging times).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from imucal.columns import ACC, GYR, SENSORS, TIME, temperature_column
from imucal.gap import session as ses
from imucal.gap.effects import EffectModel, Estimate
from imucal.gap.library.registry import register
from imucal.gap.library.spec import EffectSpec
from imucal.gap.locations import allan_deviation
from imucal.gap.streams import Stream, streams_half, white_std
from imucal.gap.wandershape import WanderColumn, wander_gate
from imucal.pipeline.full import SessionFit, calibrated

#: Correlation time (s) assumed for the Gauss-Markov part when converting the variance seen
#: over a short recording to its stationary std (typical MEMS, effects.md #3; the recording
#: is too short to estimate it).
BIAS_TAU_S = 100.0


def wander_variance(
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
#: (:func:`shows_g_sensitivity`): only then are the specific force's columns taken out of the
#: wander's regression (each costs power: the poses are grouped in time).
G_TEST_P = 1e-3


def shows_g_sensitivity(rest: ses.RestingMeans, base: np.ndarray) -> bool:
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
    gravity, from ``|a| - g``) from the variogram (:func:`wander_variance`) of the resting
    means (:func:`imucal.gap.session.resting_means`) and, for the gyroscope, the run means of
    the rate table's turning runs, on the twin's session clock.

    The wander is the bias's change with time; what else moves these means is taken out
    first, so that it is not counted as wander:

    * resting means: a constant, a line in the temperature (where a segment has no reading,
      none) and, for the gyro, the specific force when the means show a g-sensitivity
      (:func:`shows_g_sensitivity`; the Earth's vertical rate goes with it then);
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
    its standard deviation under white noise alone (:func:`wander_variance`): comparable
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
    gm2_acc, *_ = wander_variance(
        t, np.linalg.norm(rest.acc, axis=1) - g, rest.acc_var, base, BIAS_TAU_S
    )
    with_sf = n > base.shape[1] + 6 and shows_g_sensitivity(rest, base)
    design = np.column_stack([base, rest.acc]) if with_sf else base
    runs = _table_runs(fit, half)
    if runs is not None:
        ok = np.all(np.isfinite(runs["var"]), axis=1) & np.all(np.isfinite(runs["acc"]), axis=1)
        runs = {k: v[ok] for k, v in runs.items()}
        if len(runs["t"]) < 4:
            runs = None
    gm2_gyr, excess, excess_var, columns = [], 0.0, 0.0, []
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
        gm2_k, ex_k, var_k = wander_variance(times, y, var, x, BIAS_TAU_S)
        columns.append(WanderColumn(times, y, var, x))
        gm2_gyr.append(gm2_k)
        excess, excess_var = excess + ex_k, excess_var + var_k
    gm2 = float(np.mean(gm2_gyr))
    params = {
        "acc_gm": float(np.sqrt(max(gm2_acc, 0.0))), "acc_rw": 0.0, "acc_tau_s": BIAS_TAU_S,
        "gyr_gm": float(np.sqrt(max(gm2, 0.0))), "gyr_rw": 0.0, "gyr_tau_s": BIAS_TAU_S,
        "mag_gm": 0.0, "mag_rw": 0.0, "mag_tau_s": BIAS_TAU_S,
    }  # fmt: skip
    evidence = {"columns": columns, "tau_s": BIAS_TAU_S}
    if "static" in fit.imu:
        table = fit.imu["static"]
        t_static = table[TIME].to_numpy(dtype=float)
        x = np.column_stack([table[c].to_numpy(dtype=float) for c in (*ACC, *GYR)])
        x = x[np.all(np.isfinite(x), axis=1)]
        evidence["allan"] = allan_evidence(x, 1 / float(np.median(np.diff(t_static))))
    detect = excess / np.sqrt(excess_var) if excess_var > 0 else 0.0
    return Estimate(params, detect, evidence)


#: The short cluster time (samples) at which a wander's Allan shape is checked
#: (:func:`allan_evidence`): long against a sample, short against any wander.
ALLAN_SHORT_SAMPLES = 10


def allan_evidence(x: np.ndarray, rate_hz: float) -> dict | None:
    """What a wander's Allan shape is checked on (:func:`imucal.gap.wandershape.allan_shape_z`):
    each column's Allan variance at :data:`ALLAN_SHORT_SAMPLES`, its white-noise level from
    first differences (as the twin's), the cluster time and the variance's degrees of freedom
    (the recording's length in clusters). None for a recording of fewer than 20 clusters.

    Parameters
    ----------
    x : ndarray, shape (n, k)
        Samples of a static recording (SI), equally spaced at ``rate_hz``.
    rate_hz : float
    """
    m = ALLAN_SHORT_SAMPLES
    if len(x) < 20 * m:
        return None
    return {
        "avar_short": allan_deviation(x, m) ** 2,
        "white": white_std(x) ** 2 / rate_hz,
        "tau_short_s": m / rate_hz,
        "edf_short": len(x) / m - 1,
    }


def _gm_from_allan(x: np.ndarray, rate_hz: float) -> tuple[float, float]:
    """Gauss-Markov std (SI) from the Allan excess at ``min(100 s, T/5)``, and its log ratio."""
    white = white_std(x)
    tau = min(100.0, len(x) / rate_hz / 5)
    m = max(int(tau * rate_hz), 1)
    ad = allan_deviation(x, m)
    excess = np.maximum(ad**2 - white**2 / m, 0.0)
    # a first-order Gauss-Markov process's Allan deviation peaks near 0.62 of its std
    return float(np.sqrt(np.mean(excess))) / 0.62, float(np.mean(np.log(ad / (white / np.sqrt(m)))))


def estimate_static_bias_instability(streams: Mapping[str, Stream], half: str | None) -> Estimate:
    """Gauss-Markov bias std per sensor from the Allan excess; detect: mean log excess.

    The simulator's process has one std per sensor (all axes); the estimate pools the axes'
    excess variance. A magnetometer's "bias" wander includes changes of the ambient field.
    """
    streams = streams_half(streams, half)
    params, detect, shape = {}, [], []
    for s in SENSORS:
        st = next((st for st in streams.values() if s in st.values), None)
        gm = 0.0
        if st is not None:
            gm, lr = _gm_from_allan(st.values[s], st.rate_hz)
            detect.append(lr)
            if s != "mag":  # the magnetometer's slow part holds the ambient field's changes
                shape.append(allan_evidence(st.values[s], st.rate_hz))
        params.update({f"{s}_rw": 0.0, f"{s}_gm": gm, f"{s}_tau_s": BIAS_TAU_S})
    evidence = {"allan": _pooled_allan([e for e in shape if e is not None])}
    return Estimate(params, float(np.mean(detect)), evidence)


def _pooled_allan(parts: list) -> dict | None:
    """One :func:`allan_evidence` of several sensors' (their columns side by side; the times
    and degrees of freedom of the shortest recording)."""
    if not parts:
        return None
    out = {k: np.concatenate([p[k] for p in parts]) for k in ("avar_short", "white")}
    first = min(parts, key=lambda p: p["edf_short"])
    return {**out, "tau_short_s": first["tau_short_s"], "edf_short": first["edf_short"]}


BIAS_INSTABILITY = register(EffectSpec(
    name="bias_instability",
    description="slowly wandering biases: random walk plus first-order Gauss-Markov",
    kind="spread",
    scopes={
        "protocol": EffectModel("bias_instability", estimate_bias_instability,
                                (("noise", "*", "adev_long_excess"),
                                 ("noise", "*", "adev_10s_excess"),
                                 ("noise", "*", "trend_per_s"), ("gyr_static", "gyr", "spread")),
                                "wandering biases: Allan deviation above the white-noise line at "
                                "long tau", gate=wander_gate),
        "static": EffectModel("bias_instability", estimate_static_bias_instability,
                              (("noise", "*", "adev_10s_excess"),
                               ("noise", "*", "adev_long_excess"),
                               ("noise", "*", "trend_per_s")),
                              "wandering biases: Allan deviation above the white-noise line",
                              gate=wander_gate),
        "motion": "no static recording: the Allan deviation needs a long rest",
        "rests": "rests of a few seconds do not resolve a bias wander (correlation times of "
        "100 s): the twin draws white noise, and a wander the rests do show is in their Allan "
        "excess and trend, read as the twin's shortfall",
        "field_fit": "a bias wander is in the residual's slow part, with the field's changes",
    },
))  # fmt: skip
