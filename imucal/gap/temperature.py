"""Temperature polynomials of bias and scale per axis, with the order chosen on held-out data.

One estimator for the diagnosis (its order-1 fit, :func:`linear_drift`, is the effect
``temperature_drift``'s estimate) and the model term (:func:`fit_temperature`, which the term
``temperature`` calls), so that both read one parameterisation.

The estimators work on the session's resting segments (:func:`imucal.gap.session.resting_rows`:
rotation3d rests, cube positions, rate-table rest runs, the static recording in blocks) and on
the rate-table runs, each reduced to its raw mean reading and mean temperature:

- gyroscope bias: the raw resting means against ``dT^k`` per axis, with a constant and the
  calibrated specific force as nuisance regressors (so that a g-sensitivity is not taken for a
  drift between poses at different temperatures);
- gyroscope scale (rate table only): the raw run means, less the bias drift, against the
  sensor-frame rate ``u = K^-1 w`` and ``u dT^k`` per axis, with a constant per mounting
  (``K`` and the bias of eq. 33; gravity, and a g-sensitivity with it, differs between
  mountings);
- accelerometer bias and scale: ``|a| - g`` of the resting means (rate-table runs left out),
  linearised about the paper's calibration: with ``d`` the direction of the calibrated mean and
  ``u = reading - o``, a drift moves ``|a|`` by ``-(d^T K)_j (b_j(dT) + s_j(dT) u_j)``; a
  constant bias and scale change per axis (the cube fit holds at the cube's temperatures) are
  nuisance regressors.

The order (0 .. ``max_order``) is chosen on held-out segments (:func:`select_order`:
leave-one-out residuals, the smallest order within one standard error of the best); order 0
(no temperature dependence) wins when no polynomial predicts the held-out segments better. A
sensor is refused when its recording's temperature span is below ``min_span_c``. The
gyroscope bias polynomial's coefficients and standard deviations are those of generalised least
squares with the bias walking on the session clock (:func:`imucal.fits.wander.fit_with_wander`:
a walk over a warm-up looks like a drift against temperature); the other standard deviations
are those of least squares with the residual variance of the whole fit.

The calibrated span of a sensor's polynomials is that of the temperature samples its
estimators average (:func:`sample_span`: the resting segments, and for the gyroscope the
rate-table runs), not that of the segment means: a segment's samples reach beyond its mean by
the drift within it, and the session's first and last resting segments hold its coldest and
warmest samples, so the session's own samples fall outside only where they precede or follow
every segment.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from imucal.columns import AXES, GYR, SENSOR_COLUMNS, TIME, column_values, temperature_column
from imucal.fits.wander import fit_with_wander
from imucal.gap import session as st
from imucal.modelterms.temperature import TemperaturePolynomial
from imucal.pipeline.full import SessionFit, calibrated
from imucal.segments.table import row_bounds

#: Highest order of a scale polynomial: the scale is seen only in rate-table runs (one axis's
#: runs span a fraction of a kelvin) and in the gravity along an axis, too little for a curve.
SCALE_MAX_ORDER = 1


@dataclass(frozen=True)
class Means:
    """Segment means of one kind of segment, in time order within each recording.

    Attributes
    ----------
    raw : dict of str to ndarray, shape (n, 3)
        Sensor -> raw mean reading (SI, sensor frame).
    acc_b : ndarray, shape (n, 3)
        Calibrated specific force (frame B, m/s^2).
    temp_c : ndarray, shape (n,)
    gyr_white : ndarray, shape (n, 3)
        White-noise variance of the raw gyro means ((rad/s)^2, from first differences).
    t_s : ndarray, shape (n,)
        Middle of each segment on the session clock (s,
        :func:`imucal.gap.session.session_clock`).
    """

    raw: dict
    acc_b: np.ndarray
    temp_c: np.ndarray
    gyr_white: np.ndarray
    t_s: np.ndarray


def _segment_means(fit: SessionFit, segments: list) -> Means:
    raw = {s: [] for s in ("acc", "gyr")}
    acc_b, temp, white, mid = [], [], [], []
    clock = st.session_clock(fit)
    quantum = float(fit.extra["options"].sensitivity["gyr"])
    for rec, rows in segments:
        table = fit.imu[rec]
        col = temperature_column(table)
        if col is None or rows.empty:
            continue
        t = st.segment_means(table[[col]].to_numpy(dtype=float), rows)[:, 0]
        readings = {s: column_values(table, SENSOR_COLUMNS[s]) for s in raw}
        for s in raw:
            raw[s].append(st.segment_means(readings[s], rows))
        acc_b.append(st.segment_means(np.asarray(calibrated(fit, rec, "acc")), rows))
        gyr = readings["gyr"]
        white.append([_white_variance(gyr[a:b], quantum) for a, b in row_bounds(rows)])
        start = float(table[TIME].iloc[0])
        mid.append(clock[rec] + st.mid_times(fit, rec, rows) - start)
        temp.append(t)
    if not temp:
        empty = np.zeros((0, 3))
        return Means({s: empty for s in raw}, empty, np.zeros(0), empty, np.zeros(0))
    out = Means(
        {s: np.vstack(v) for s, v in raw.items()},
        np.vstack(acc_b),
        np.concatenate(temp),
        np.vstack(white).reshape(-1, 3),
        np.concatenate(mid),
    )
    ok = np.isfinite(out.temp_c) & np.all(np.isfinite(out.raw["gyr"]), axis=1)
    ok &= np.all(np.isfinite(out.raw["acc"]), axis=1) & np.all(np.isfinite(out.gyr_white), axis=1)
    return Means({s: v[ok] for s, v in out.raw.items()}, out.acc_b[ok], out.temp_c[ok],
                 out.gyr_white[ok], out.t_s[ok])  # fmt: skip


def _white_variance(x: np.ndarray, quantum: float) -> np.ndarray:
    """White-noise variance of the mean of the complete rows of ``x`` (n, 3), per column, at
    least the quantisation's (``quantum^2 / 12`` per sample: a resting quantised reading may
    not change at all); NaN with fewer than 3 rows."""
    x = x[np.all(np.isfinite(x), axis=1)]
    return st.white_variance(x, quantum**2 / 12) if len(x) >= 3 else np.full(3, np.nan)


def resting_means(fit: SessionFit, *, table: bool = True, half: str | None = None) -> Means:
    """Raw means of the session's resting segments with a temperature reading (rate-table rest
    runs left out when ``table`` is False; every other segment for ``half`` 'A' or 'B', as
    :func:`imucal.gap.session.resting_rows`)."""
    segments = [(r, rows) for r, rows in st.resting_rows(fit, half) if table or r != "ratetable"]
    return _segment_means(fit, segments)


def sample_span(fit: SessionFit, *, table: bool) -> tuple[float, float]:
    """Lowest and highest temperature sample (deg C) of the resting segments, with the
    rate-table runs at every rate when ``table`` (else without the rate table at all)."""
    segments = [(r, rows) for r, rows in st.resting_rows(fit, None) if r != "ratetable"]
    if table and "ratetable" in fit.imu:
        segments.append(("ratetable", st.segment_rows(fit, "ratetable", "run")))
    found = []
    for rec, rows in segments:
        col = temperature_column(fit.imu[rec])
        if col is None:
            continue
        temp = fit.imu[rec][col].to_numpy(dtype=float)
        found += [temp[int(r.start_index) : int(r.end_index)] for r in rows.itertuples()]
    temp = np.concatenate(found) if found else np.zeros(0)
    temp = temp[np.isfinite(temp)]
    return float(temp.min()), float(temp.max())


def _powers(d_t: np.ndarray, order: int) -> np.ndarray:
    """Columns ``dT^1 .. dT^order``, shape (n, order)."""
    return (
        np.column_stack([d_t**k for k in range(1, order + 1)]) if order else np.zeros((len(d_t), 0))
    )


def _lstsq(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Coefficients (m, k) and their standard deviations of ``y (n, k) ~ x (n, m)``."""
    coef, *_ = np.linalg.lstsq(x, y, rcond=None)
    dof = max(len(x) - x.shape[1], 1)
    sigma2 = np.sum((y - x @ coef) ** 2, axis=0) / dof
    cov = np.linalg.pinv(x.T @ x)
    return coef, np.sqrt(np.clip(np.diag(cov), 0, None))[:, None] * np.sqrt(sigma2)[None, :]


def heldout_residuals(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Leave-one-out residuals of the least-squares fit ``y (n, k) ~ x (n, m)``: each segment
    predicted from a fit on all the others (``e_i / (1 - h_ii)``), shape (n, k); NaN when the
    fit has no more segments than columns or a segment alone determines a coefficient."""
    n, m = x.shape
    if n <= m + 1:
        return np.full(y.shape, np.nan)
    pinv = np.linalg.pinv(x)
    h = np.einsum("ij,ji->i", x, pinv)
    if np.any(h > 1 - 1e-9):
        return np.full(y.shape, np.nan)
    e = y - x @ (pinv @ y)
    return e / (1 - h).reshape((-1,) + (1,) * (y.ndim - 1))


def select_model(candidates: dict, y: np.ndarray) -> tuple:
    """The candidate design chosen on held-out residuals, and the held-out RMS of each.

    The held-out residuals are leave-one-out (:func:`heldout_residuals`). The choice is the
    candidate with the fewest columns whose mean squared held-out residual is within one
    standard error of the smallest (the one-standard-error rule: a larger model has to predict
    better by more than the noise of the comparison).

    Parameters
    ----------
    candidates : dict
        Key -> design matrix, shape (n, m); the first key is the model without temperature.
    y : ndarray, shape (n,) or (n, k)

    Returns
    -------
    key
        The chosen candidate (the first when no other beats it on held-out data).
    heldout : dict
        Key -> held-out RMS (NaN where there are too few segments for that design).
    """
    sq = {}
    for key, x in candidates.items():
        e = heldout_residuals(x, y)
        sq[key] = np.sum(np.reshape(e, (len(y), -1)) ** 2, axis=1)
    heldout = {k: float(np.sqrt(np.mean(v))) for k, v in sq.items()}
    finite = {k: v for k, v in sq.items() if np.all(np.isfinite(v))}
    first = next(iter(candidates))
    if not finite:
        return first, heldout
    best = min(finite, key=lambda k: finite[k].mean())
    bound = finite[best].mean() + finite[best].std(ddof=1) / np.sqrt(len(y))
    within = [k for k, v in finite.items() if v.mean() <= bound]
    return min(within, key=lambda k: candidates[k].shape[1]), heldout


def _refusal(temp: np.ndarray, min_span_c: float, what: str) -> str:
    if len(temp) < 6:
        return f"{what}: {len(temp)} resting segments with a temperature reading, at least 6 needed"
    span = float(np.ptp(temp))
    if span < min_span_c:
        return (
            f"{what}: the temperature span of the session's resting segments is {span:.2f} K, "
            f"below the {min_span_c:g} K a temperature polynomial needs (temperature_min_span_c)"
        )
    return ""


def _gyro(
    fit: SessionFit, rest: Means, reference_c: float, max_order: int, order: int | None = None
) -> tuple:
    """Bias polynomial of the gyroscope: coefficients (p, 3), std (p, 3), each axis's
    covariance (3, p, p), held-out evidence. ``order`` fixes the order (no selection)."""
    d_t = rest.temp_c - reference_c
    n = len(d_t)
    nuisance = [np.ones((n, 1))]
    # enough segments to take a g-sensitivity out as well (with the order fixed, twice the
    # columns of the fit; with the order to choose, room for the highest one on held-out data)
    enough = n > 2 * (4 + order) if order is not None else n > 3 * (max_order + 5)
    if enough:
        nuisance.append(rest.acc_b)

    def design(order):
        return np.column_stack([*nuisance, _powers(d_t, order)])

    y = rest.raw["gyr"]
    if order is None:
        order, heldout = select_model({k: design(k) for k in range(max_order + 1)}, y)
    else:
        heldout = {}
    fits = [fit_with_wander(design(order), y[:, j], rest.gyr_white[:, j], rest.t_s)
            for j in range(3)]  # fmt: skip
    coef = np.column_stack([f.coef for f in fits])
    std = np.column_stack([np.sqrt(np.diag(f.cov)) for f in fits])
    p = design(0).shape[1]
    covariance = np.array([f.cov[p:, p:] for f in fits])
    evidence = {
        "order": order,
        "heldout_rms": heldout,
        "unit": "rad/s",
        "segments": n,
        "walk_per_s": [f.walk_per_s for f in fits],
    }
    return coef[p:], std[p:], covariance, evidence


def _gyro_scale(
    fit: SessionFit,
    bias_poly: np.ndarray,
    reference_c: float,
    max_order: int,
    order: int | None = None,
    half: str | None = None,
):
    """Scale polynomial of the gyroscope from the rate-table runs (None without a table);
    ``order`` fixes the order (no selection), ``half`` takes every other run."""
    table = fit.artifacts["gyr_table"]
    if table is None or "ratetable" not in fit.imu:
        return None
    rows, _, true = st.table_residuals(fit, half)
    col = temperature_column(fit.imu["ratetable"])
    if col is None or len(rows) < 8:
        return None
    means = st.segment_means(fit.imu["ratetable"][list(GYR)].to_numpy(dtype=float), rows)
    temp = st.segment_means(fit.imu["ratetable"][[col]].to_numpy(dtype=float), rows)[:, 0]
    k = np.asarray(table["matrix"], dtype=float)
    u = np.linalg.solve(k, true.T).T
    d_t = temp - reference_c
    y = means - _powers(d_t, len(bias_poly)) @ bias_poly if len(bias_poly) else means
    coefs, stds = [], []

    # a constant per mounting (the turning axis): gravity lies along another direction of B
    # on each, and a g-sensitivity with it, which a constant per axis would leave in the runs
    # of one mounting, where the temperature rises with the run order
    axis = rows["axis"].to_numpy()
    mount = np.column_stack([(axis == a).astype(float) for a in np.unique(axis)])
    n_m = mount.shape[1]

    # one order for the three axes: stacked, each axis with its own columns
    def design(order):
        blocks = [
            np.column_stack([mount, u[:, j], u[:, [j]] * _powers(d_t, order)]) for j in range(3)
        ]
        return blocks

    def stacked(order):
        blocks = design(order)
        m = blocks[0].shape[1]
        out = np.zeros((3 * len(u), 3 * m))
        for j, b in enumerate(blocks):
            out[j * len(u) : (j + 1) * len(u), j * m : (j + 1) * m] = b
        return out

    if order is None:
        order, heldout = select_model(
            {k: stacked(k) for k in range(SCALE_MAX_ORDER + 1)}, y.T.ravel()
        )
    else:
        heldout = {}
    designs = [lambda o, j=j: design(o)[j] for j in range(3)]
    for j in range(3):
        c, s = _lstsq(designs[j](order), y[:, [j]])
        # u (1 + s(dT)): the coefficients of u dT^k over that of u
        coefs.append(c[n_m + 1 :, 0] / c[n_m, 0])
        stds.append(s[n_m + 1 :, 0] / abs(c[n_m, 0]))
    return (
        np.column_stack(coefs).reshape(order, 3),
        np.column_stack(stds).reshape(order, 3),
        {"order": order, "heldout_rms": heldout, "unit": "rad/s", "runs": len(rows)},
    )


def _acc(
    fit: SessionFit, rest: Means, reference_c: float, max_order: int, min_order: int = 0
) -> tuple:
    """Bias and scale polynomials of the accelerometer from ``|a| - g`` of resting means.

    Candidates: bias orders ``min_order`` .. ``max_order`` per axis, each with no scale drift, a common
    scale drift of order 1 or one per axis of order 1 (resting poses see the scale of an axis
    only through the gravity along it, so a scale per axis needs poses along every axis at
    several temperatures)."""
    cal = fit.calibration.sensor("acc")
    k, o = cal.matrix, cal.bias
    g = fit.extra["options"].gravity_m_s2
    u = rest.raw["acc"] - o
    a = u @ k.T
    norm = np.linalg.norm(a, axis=1)
    dk = (a / norm[:, None]) @ k  # d^T K, shape (n, 3)
    y = norm - g
    d_t = rest.temp_c - reference_c
    common = (dk * u).sum(axis=1, keepdims=True)
    candidates, layout = {}, {}
    for scale in ("none", "common", "per_axis"):
        # the cube fit holds at the cube's temperatures: a constant bias change and scale
        # change move it to reference_c
        nuisance = [dk] + {"none": [], "common": [common], "per_axis": [dk * u]}[scale]
        for order in range(min_order, max_order + 1):
            cols = nuisance + [dk * d_t[:, None] ** kk for kk in range(1, order + 1)]
            if scale != "none":
                cols.append({"common": common, "per_axis": dk * u}[scale] * d_t[:, None])
            candidates[(order, scale)] = np.column_stack(cols)
            layout[(order, scale)] = sum(c.shape[1] for c in nuisance)
    (order, scale), heldout = select_model(candidates, y)
    coef, std = _lstsq(candidates[(order, scale)], y[:, None])
    c, s = coef[layout[(order, scale)] :, 0], std[layout[(order, scale)] :, 0]
    bias, bias_std = c[: 3 * order].reshape(order, 3), s[: 3 * order].reshape(order, 3)
    rest_c, rest_s = c[3 * order :], s[3 * order :]
    if scale == "common":
        rest_c, rest_s = np.repeat(rest_c, 3), np.repeat(rest_s, 3)
    q = 0 if scale == "none" else 1
    evidence = {
        "order": order,
        "scale": scale,
        "heldout_rms": {f"bias {o_}, scale {s_}": v for (o_, s_), v in heldout.items()},
        "unit": "m/s^2 (|a| - g)",
        "segments": len(y),
        "without": "bias 0, scale none",
        "with": f"bias {order}, scale {scale}",
    }
    return bias, bias_std, rest_c.reshape(q, 3), rest_s.reshape(q, 3), evidence


def linear_drift(fit: SessionFit, half: str | None = None) -> dict | None:
    """First-order drift per axis of the gyroscope and the accelerometer.

    The estimators of :func:`fit_temperature` at bias order 1 without the order selection: the
    parameterisation of the simulator's ``temperature_drift`` (bias and relative scale per
    kelvin of each raw axis, either sign). The gyroscope's bias comes with a constant and the
    calibrated specific force as nuisance (a g-sensitivity is not taken for a drift; both are
    one regression), its scale from the rate-table runs (0 without a table); the
    accelerometer's scale model (none, common, per axis) is still chosen on held-out segments,
    since resting poses see an axis's scale only through the gravity along it.

    Parameters
    ----------
    fit : SessionFit
    half : str, optional
        'A' or 'B': every other resting segment and rate-table run (the diagnosis's halves).

    Returns
    -------
    dict or None
        ``'gyr'``, ``'acc'`` -> ``bias``, ``scale``, ``bias_std``, ``scale_std`` (each shape
        (3,), SI/K and 1/K), and ``reference_c``; None when fewer than 6 resting segments
        have a temperature reading or their temperature does not change.
    """
    rest = resting_means(fit, half=half)
    if len(rest.temp_c) < 6 or not np.ptp(rest.temp_c) > 0:
        return None
    reference_c = 0.5 * float(rest.temp_c.min() + rest.temp_c.max())
    zero = np.zeros(3)
    bias, bias_std, _, _ = _gyro(fit, rest, reference_c, 1, order=1)
    scale = _gyro_scale(fit, bias, reference_c, 1, order=1, half=half)
    out = {
        "reference_c": reference_c,
        "gyr": {
            "bias": bias[0], "bias_std": bias_std[0],
            "scale": scale[0][0] if scale is not None else zero,
            "scale_std": scale[1][0] if scale is not None else zero,
        },
        "acc": {"bias": zero, "scale": zero, "bias_std": zero, "scale_std": zero},
    }  # fmt: skip
    acc_rest = resting_means(fit, table=False, half=half)
    if len(acc_rest.temp_c) >= 8 and np.ptp(acc_rest.temp_c) > 0:
        b, b_std, s, s_std, _ = _acc(fit, acc_rest, reference_c, 1, min_order=1)
        out["acc"] = {
            "bias": b[0], "bias_std": b_std[0],
            "scale": s[0] if len(s) else zero, "scale_std": s_std[0] if len(s) else zero,
        }  # fmt: skip
    return out


def fit_temperature(
    fit: SessionFit, *, max_order: int, min_span_c: float, margin_c: float
) -> tuple[dict, dict]:
    """Temperature polynomials of the gyroscope and the accelerometer of a session.

    Parameters
    ----------
    fit : SessionFit
        The session calibrated with the paper's model.
    max_order : int
        Highest polynomial order tried (>= 1).
    min_span_c : float
        Smallest temperature span (K) of the resting segments for a polynomial.
    margin_c : float
        How far outside the fitted span (K) the polynomial may be applied (stored in the term).

    Returns
    -------
    polynomials : dict of str to TemperaturePolynomial
        Sensor -> its polynomials, for the sensors where an order >= 1 won on held-out data.
    evidence : dict
        Sensor -> ``order``, ``heldout_rms`` (order -> RMS), ``unit``, or ``refused`` (the
        reason); ``span_c`` (of the resting segments' means), ``sample_span_c`` (per sensor,
        of the samples: the polynomials' calibrated span) and ``reference_c``.
    """
    if max_order < 1:
        raise ValueError(f"temperature max_order must be >= 1, got {max_order}")
    rest = resting_means(fit)
    if not len(rest.temp_c):
        reason = "the session has no temperature channel (or no resting segment with a reading)"
        return {}, {"refused": reason}
    lo, hi = float(rest.temp_c.min()), float(rest.temp_c.max())
    reference_c = round(0.5 * (lo + hi), 2)
    evidence: dict = {"span_c": [lo, hi], "reference_c": reference_c, "segments": len(rest.temp_c)}
    polys = {}
    refusal = _refusal(rest.temp_c, min_span_c, "temperature")
    if refusal:
        return {}, {**evidence, "refused": refusal}
    spans = {"gyr": sample_span(fit, table=True), "acc": sample_span(fit, table=False)}
    evidence["sample_span_c"] = {s: list(v) for s, v in spans.items()}
    session = np.concatenate(
        [t[c].to_numpy(dtype=float) for t in fit.imu.values() if (c := temperature_column(t))]
    )
    lo_s, hi_s = spans["acc"]
    beyond = float(np.nanmax(np.maximum(lo_s - session, session - hi_s)))
    if beyond > margin_c:
        refusal = (
            f"temperature: the session's own samples reach {beyond:.2f} K outside the span of "
            f"its resting segments ({lo_s:.2f}..{hi_s:.2f} deg C), more than the margin "
            f"{margin_c:g} K"
        )
        return {}, {**evidence, "refused": refusal}

    bias, bias_std, bias_cov, ev_g = _gyro(fit, rest, reference_c, max_order)
    scale = _gyro_scale(fit, bias, reference_c, max_order)
    ev_gyr = {"bias": ev_g}
    if scale is not None:
        ev_gyr["scale"] = scale[2]
    if len(bias) or (scale is not None and len(scale[0])):
        polys["gyr"] = TemperaturePolynomial(
            "gyr", reference_c, spans["gyr"], margin_c, bias,
            scale[0] if scale is not None else np.zeros((0, 3)), bias_std,
            scale[1] if scale is not None else np.zeros((0, 3)),
            "bias: raw resting means against dT^k (constant and specific force as nuisance); "
            "scale: rate-table run means against u dT^k (u = K^-1 w of eq. 33); "
            "orders by leave-one-out residuals (one-standard-error rule)",
            bias_cov if len(bias) else None,
        )  # fmt: skip
    else:
        ev_gyr["refused"] = "no polynomial order predicts held-out segments better than none"
    evidence["gyr"] = ev_gyr

    acc_rest = resting_means(fit, table=False)
    refusal = _refusal(acc_rest.temp_c, min_span_c, "acc temperature")
    if refusal:
        evidence["acc"] = {"refused": refusal}
    else:
        b, b_std, s, s_std, ev_a = _acc(fit, acc_rest, reference_c, max_order)
        evidence["acc"] = ev_a
        if ev_a["order"] or ev_a["scale"] != "none":
            polys["acc"] = TemperaturePolynomial(
                "acc", reference_c, spans["acc"], margin_c, b, s, b_std, s_std,
                "|a| - g of resting means (rate-table runs left out) linearised about the cube "
                "fit, a constant bias and scale change as nuisance; model by leave-one-out "
                "residuals (one-standard-error rule)",
            )  # fmt: skip
        else:
            ev_a["refused"] = "no polynomial order predicts held-out segments better than none"
    for s in ("gyr", "acc"):
        evidence[s]["axes"] = list(AXES)
    return polys, evidence
