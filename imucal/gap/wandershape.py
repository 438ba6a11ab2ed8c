"""Whether a wandering bias has the shape of a wander: the test a spread effect must pass.

A wandering bias (``bias_instability``: Gauss-Markov plus random walk) widens the twin's null;
any slow departure of the resting means then looks typical, and the held-out shrink rewards the
widening. So the wander is judged on the shape of its own statistics: under the fitted wander,
the resting means' one-step-ahead innovations (generalised least squares in time order, the
regressors taken out) are independent standard normal draws. A bias that jumps once leaves a
few large innovations among many small ones (heavy tails, too little spread elsewhere); an
offset that follows the orientation (a force the library lacks) leaves too much spread at the
orientations that repeat. Neither is a wander, whatever the widened null holds.

The wander's variances are fitted by moments on every pair's squared difference (a
Gauss-Markov part of correlation time ``tau_s`` and a random walk, both at least 0), the
innovations scaled by their leverage, and two statistics taken over the innovations of every
column: their dispersion ``(mean u^2 - 1) sqrt(N / 2)`` (two-sided) and their kurtosis
``(kurt - 3) / sqrt(24 / N)`` (heavy tails). The p-value of the larger of the two is taken from
a parametric bootstrap of the fitted model (the variances refitted on every draw), so that the
plug-in of the fitted variances is in the null.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import nnls

#: Parametric bootstrap draws of the shape test's null.
BOOTSTRAP = 500


@dataclass(frozen=True)
class WanderColumn:
    """One column of means a wander acts on.

    Attributes
    ----------
    t_s : ndarray, shape (n,)
        Session time of each mean (s).
    y : ndarray, shape (n,)
        The means (SI).
    var : ndarray, shape (n,)
        White-noise variance of each mean (SI^2).
    design : ndarray, shape (n, p)
        Regressors taken out (a constant, temperature, ...).
    """

    t_s: np.ndarray
    y: np.ndarray
    var: np.ndarray
    design: np.ndarray


def _kernels(t: np.ndarray, tau_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Covariance kernels of the Gauss-Markov part (unit variance) and of the random walk
    (unit variance per second, from the first mean)."""
    gm = np.exp(-np.abs(t[:, None] - t[None, :]) / tau_s)
    t0 = t - t.min()
    return gm, np.minimum(t0[:, None], t0[None, :])


def fit_wander(column: WanderColumn, tau_s: float) -> tuple[float, float]:
    """Gauss-Markov variance ``gm^2`` (SI^2) and random-walk rate ``q`` (SI^2/s) of a column's
    wander, by non-negative least squares of the pairs' squared differences of the residuals
    (the regressors taken out) on what the white noise and each part make them, weighted by
    the white noise's."""
    m = np.eye(len(column.t_s)) - column.design @ np.linalg.pinv(column.design)
    r = m @ column.y
    gm, rw = _kernels(column.t_s, tau_s)
    iu = np.triu_indices(len(r), 1)

    def pairs(s: np.ndarray) -> np.ndarray:
        d = np.diag(s)
        return (d[:, None] + d[None, :] - 2 * s)[iu]

    noise = pairs(m @ np.diag(column.var) @ m)
    weight = 1 / np.sqrt(np.maximum(noise, 1e-300))
    obs = (r[:, None] - r[None, :])[iu] ** 2 - noise
    parts = np.column_stack([pairs(m @ gm @ m), pairs(m @ rw @ m)])
    (gm2, q), _ = nnls(parts * weight[:, None], obs * weight)
    return float(gm2), float(q)


def innovations(column: WanderColumn, gm2: float, q: float, tau_s: float) -> np.ndarray:
    """The column's one-step-ahead innovations under white noise plus the wander, in time
    order, each over its standard deviation (the leverage of the regressors taken out)."""
    order = np.argsort(column.t_s)
    t, y, var, x = (a[order] for a in (column.t_s, column.y, column.var, column.design))
    gm, rw = _kernels(t, tau_s)
    v = np.diag(var) + gm2 * gm + q * rw
    chol = np.linalg.cholesky(v + 1e-12 * np.mean(var) * np.eye(len(t)))
    xw, yw = np.linalg.solve(chol, x), np.linalg.solve(chol, y)
    beta, *_ = np.linalg.lstsq(xw, yw, rcond=None)
    leverage = np.einsum("ij,ji->i", xw, np.linalg.pinv(xw))
    return (yw - xw @ beta) / np.sqrt(np.maximum(1 - leverage, 1e-9))


def shape_statistics(u: np.ndarray) -> tuple[float, float]:
    """Dispersion and kurtosis scores of innovations that should be standard normal."""
    n = len(u)
    m2 = float(np.mean(u**2))
    return (m2 - 1) * np.sqrt(n / 2), (float(np.mean(u**4)) / m2**2 - 3) / np.sqrt(24 / n)


def _score(columns: Sequence[WanderColumn], tau_s: float) -> tuple[float, float, list]:
    fitted = [fit_wander(c, tau_s) for c in columns]
    u = np.concatenate([innovations(c, g, q, tau_s) for c, (g, q) in zip(columns, fitted)])
    dispersion, kurtosis = shape_statistics(u)
    return dispersion, kurtosis, fitted


def wander_shape(
    columns: Sequence[WanderColumn],
    tau_s: float,
    rng: np.random.Generator,
    n_boot: int = BOOTSTRAP,
) -> dict:
    """The shape test of a wander fitted to columns of means (module docstring).

    Parameters
    ----------
    columns : sequence of WanderColumn
        The means a wander acts on (the gyroscope's axes, say), each with its own variances.
    tau_s : float
        Correlation time of the Gauss-Markov part (s).
    rng : numpy.random.Generator
        Draws of the parametric bootstrap.
    n_boot : int

    Returns
    -------
    dict
        ``dispersion``, ``kurtosis`` (the scores), ``p`` (bootstrap p-value of the larger of
        ``|dispersion|`` and ``kurtosis``), ``gm`` (SI) and ``rw`` (SI/sqrt(s)) per column,
        ``innovations`` (how many).
    """
    dispersion, kurtosis, fitted = _score(columns, tau_s)
    observed = max(abs(dispersion), kurtosis)
    exceed = 0
    for _ in range(n_boot):
        drawn = []
        for c, (gm2, q) in zip(columns, fitted):
            gm, rw = _kernels(c.t_s, tau_s)
            v = np.diag(c.var) + gm2 * gm + q * rw
            chol = np.linalg.cholesky(v + 1e-12 * np.mean(c.var) * np.eye(len(c.t_s)))
            y = chol @ rng.standard_normal(len(c.t_s))
            drawn.append(WanderColumn(c.t_s, y, c.var, c.design))
        d, k, _ = _score(drawn, tau_s)
        exceed += max(abs(d), k) >= observed
    return {
        "dispersion": float(dispersion),
        "kurtosis": float(kurtosis),
        "p": (exceed + 1) / (n_boot + 1),
        "gm": [float(np.sqrt(g)) for g, _ in fitted],
        "rw": [float(np.sqrt(q)) for _, q in fitted],
        "innovations": int(sum(len(c.t_s) for c in columns)),
    }


def gauss_markov_avar(tau_s: np.ndarray, variance: float, correlation_s: float) -> np.ndarray:
    """Allan variance of a first-order Gauss-Markov rate of variance ``variance`` (SI^2) and
    correlation time ``correlation_s`` at cluster times ``tau_s`` (s): the variance of a
    cluster mean less the covariance of neighbouring ones."""
    tau = np.asarray(tau_s, dtype=float)
    x = correlation_s / tau
    decay = -np.expm1(-1 / x)
    return variance * (2 * x * (1 - x * decay) - x**2 * decay**2)


def allan_shape_z(
    avar_short: np.ndarray, white: np.ndarray, tau_short_s: float, edf_short: float
) -> np.ndarray:
    """Whether a static recording's Allan excess is there at short times, where no wander is.

    At a cluster time of a few samples a wander of correlation times of seconds to minutes
    (a Gauss-Markov bias, a random walk) adds next to nothing to the Allan variance
    (:func:`gauss_markov_avar`: ``2 tau / (3 T)`` of its variance; a walk ``q tau / 3``), so
    the Allan variance there is the white noise's. An excess over the twin's white-noise line
    at that time is not a wander: the white noise itself is off (a filtered output, whose
    first differences understate its level). The score is the observed Allan variance over the
    white line's, less one, in units of its relative standard deviation ``sqrt(2 / edf)``.

    Parameters
    ----------
    avar_short : ndarray, shape (k,)
        Allan variance of each axis at the short cluster time (SI^2).
    white : ndarray, shape (k,)
        The twin's white-noise level of one sample, as an Allan variance at 1 s (SI^2 s).
    tau_short_s : float
    edf_short : float
        Equivalent degrees of freedom of the short-time Allan variance.

    Returns
    -------
    ndarray, shape (k,)
    """
    predicted = np.asarray(white) / tau_short_s
    return (np.asarray(avar_short) / predicted - 1) / np.sqrt(2 / edf_short)


#: Level of the shape test below which a fitted wander is refused (:func:`wander_gate`).
SHAPE_P = 0.01


def wander_gate(estimate, null: Sequence, z: float) -> str:
    """A wandering bias has a wander's shape: the resting means' innovations under the fitted
    wander are standard normal, and a static recording's excess over white noise is absent at
    short cluster times. Returns the reason the estimate is not a wander, or ''.

    Reads the estimate's ``evidence``: ``columns`` (:class:`WanderColumn` of the means it was
    fitted on, and ``tau_s``) for the innovations' shape (:func:`wander_shape`, refused below
    :data:`SHAPE_P`), and ``allan`` (the static recording's Allan variances at a short and a
    long cluster time with the twin's white noise, :func:`allan_shape_z`) for an excess that
    is there at short times too (refused beyond ``z``). ``null`` is not needed: both tests
    have their own null.
    """
    evidence = getattr(estimate, "evidence", {}) or {}
    reasons = []
    allan = evidence.get("allan")
    if allan is not None:
        scores = allan_shape_z(**allan)
        worst = float(np.nanmax(scores)) if np.any(np.isfinite(scores)) else float("nan")
        if worst > z:
            reasons.append(
                f"the static recording's Allan variance at {allan['tau_short_s']:g} s is "
                f"{worst:.1f} std above the twin's white noise, where a wander adds nothing: the "
                "white noise itself is off (a filtered output?), not a wander"
            )
    columns = evidence.get("columns")
    if columns:
        shape = wander_shape(columns, evidence["tau_s"], np.random.default_rng(0))
        if shape["p"] < SHAPE_P:
            reasons.append(
                f"the resting means' innovations under the fitted wander are not standard "
                f"normal (dispersion {shape['dispersion']:+.1f}, kurtosis {shape['kurtosis']:+.1f} "
                f"std; p = {shape['p']:.3f}): their departures have the shape of a step or of "
                "an offset that follows the pose, not of a wander"
            )
    return "; ".join(reasons)
