"""IEEE Std 952 / 1293 noise terms fitted to an Allan deviation.

The Allan variance of a sum of independent noises is the sum of theirs (IEEE Std 952-1997,
Annex C, eqs. C.2-C.12; IEEE Std 1293-1998, Annex C, for accelerometers):

    sigma^2(tau) = 3 Q^2 / tau^2            quantisation, Q in U s
                 + N^2 / tau                white rate noise (angle / velocity random walk),
                                            N in U / sqrt(Hz)
                 + (2 ln 2 / pi) B^2        bias instability (flicker), B in U
                 + K^2 tau / 3              rate random walk, K in U / s / sqrt(Hz)
                 + R^2 tau^2 / 2            rate ramp, R in U / s

with U the unit of the rate samples (rad/s, m/s^2, normalised field). The five coefficients are
linear in the variance, so the fit is a non-negative least-squares problem; it is weighted by the
variance of each Allan-variance estimate, ``2 sigma^4 / edf``, with the equivalent degrees of
freedom of the noise type that dominates there, and iterated with the weights taken from the
model (iteratively reweighted least squares; weights from the noisy estimates themselves would
bias the fit low). A term is *resolved* when it dominates the model at one averaging time at
least and its coefficient exceeds twice its standard error; for a term that is not, the largest
value the recording allows is given instead (``upper_bound``: the term alone may not exceed the
upper confidence bound at any averaging time). A correlated (first-order Gauss-Markov) bias is
not one of the terms: it shows as a bump that the five cannot follow, and the reduced chi-square
of the fit then lies far above 1, which the result reports.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import nnls

from imucal.noise.allan import ALPHA, AllanDeviation, confidence_interval, equivalent_dof

#: The noise terms in model order, and the Allan-variance basis of each coefficient.
TERMS = ("Q", "N", "B", "K")
TERM_NAMES = {
    "Q": "quantisation",
    "N": "white noise (random walk of the integral)",
    "B": "bias instability",
    "K": "rate random walk",
    "R": "rate ramp",
}
#: Noise type (PSD exponent, :data:`imucal.noise.allan.ALPHA`) of each term, for the degrees of
#: freedom; the ramp is not a power law of the rate and takes the steepest one allowed.
TERM_ALPHA = {
    "Q": ALPHA["quantisation"],
    "N": ALPHA["white"],
    "B": ALPHA["flicker"],
    "K": ALPHA["random_walk"],
    "R": ALPHA["random_walk"],
}
#: sigma^2 = coefficient * basis(tau); parameter = sqrt(coefficient / FACTOR).
_FACTOR = {"Q": 3.0, "N": 1.0, "B": 2.0 * np.log(2.0) / np.pi, "K": 1.0 / 3.0, "R": 0.5}
_POWER = {"Q": -2, "N": -1, "B": 0, "K": 1, "R": 2}
#: Iterations of the reweighted fit (the weights settle within three on simulated data).
ITERATIONS = 6
#: Flat Allan deviation of bias instability relative to B: sqrt(2 ln 2 / pi) (IEEE 952 C.4).
FLICKER_FLOOR = float(np.sqrt(_FACTOR["B"]))


def term_unit(term: str, unit: str) -> str:
    """Unit of a term's parameter for rate samples in ``unit`` (e.g. 'rad/s')."""
    return {
        "Q": f"({unit}) s",
        "N": f"({unit})/sqrt(Hz)",
        "B": unit,
        "K": f"({unit})/s/sqrt(Hz)",
        "R": f"({unit})/s",
    }[term]


def term_adev(term: str, value: float, tau_s: np.ndarray) -> np.ndarray:
    """Allan deviation of one term with parameter ``value`` at ``tau_s`` (shape (k,))."""
    tau_s = np.asarray(tau_s, dtype=float)
    return np.sqrt(_FACTOR[term] * value**2 * tau_s ** _POWER[term])


@dataclass(frozen=True)
class TermFit:
    """One fitted noise term.

    Attributes
    ----------
    term : str
        One of :data:`TERMS`.
    value : float or None
        Fitted parameter (unit :func:`term_unit`); None when not resolved.
    std : float or None
        Its standard error from the weighted fit (linearised); None when not resolved.
    upper_bound : float
        Largest parameter the Allan deviation allows (at its upper confidence bound).
    resolved : bool
    """

    term: str
    value: float | None
    std: float | None
    upper_bound: float
    resolved: bool

    def to_dict(self, unit: str) -> dict:
        return {
            "value": self.value,
            "std": self.std,
            "upper_bound": self.upper_bound,
            "resolved": self.resolved,
            "unit": term_unit(self.term, unit),
            "name": TERM_NAMES[self.term],
        }


@dataclass(frozen=True)
class NoiseFit:
    """Allan deviation of one axis, its confidence interval and the fitted terms.

    Attributes
    ----------
    adev : AllanDeviation
    edf : ndarray, shape (k,)
        Equivalent degrees of freedom (noise type of the dominant fitted term).
    ci_low, ci_high : ndarray, shape (k,)
        Confidence bounds of the Allan deviation at ``level``.
    level : float
        Two-sided confidence level.
    terms : dict of str to TermFit
    model_adev : ndarray, shape (k,)
        Allan deviation of the fitted model.
    dominant : tuple of str, length k
        The term that dominates the model at each averaging time.
    reduced_chi2 : float
        Weighted residual sum of squares per degree of freedom (about 1 when the model fits).
    """

    adev: AllanDeviation
    edf: np.ndarray
    ci_low: np.ndarray
    ci_high: np.ndarray
    level: float
    terms: dict
    model_adev: np.ndarray
    dominant: tuple
    reduced_chi2: float

    def value(self, term: str) -> float | None:
        return self.terms[term].value

    def to_dict(self, unit: str) -> dict:
        return {
            "tau_s": self.adev.tau_s.tolist(),
            "adev": self.adev.adev.tolist(),
            "ci_low": self.ci_low.tolist(),
            "ci_high": self.ci_high.tolist(),
            "edf": self.edf.tolist(),
            "model_adev": self.model_adev.tolist(),
            "dominant": list(self.dominant),
            "n_phase": self.adev.n_phase,
            "reduced_chi2": self.reduced_chi2,
            "terms": {t: f.to_dict(unit) for t, f in self.terms.items()},
        }


def _basis(tau_s: np.ndarray) -> np.ndarray:
    return np.column_stack([tau_s ** _POWER[t] for t in TERMS])


def fit_noise_terms(adev: AllanDeviation, *, level: float) -> NoiseFit:
    """Fit the IEEE 952 terms to an Allan deviation (weighted, non-negative, reweighted).

    Parameters
    ----------
    adev : AllanDeviation
        From :func:`imucal.noise.allan.overlapping_adev`, at least 3 averaging times.
    level : float
        Two-sided confidence level of the reported interval and of ``upper_bound``.

    Returns
    -------
    NoiseFit

    Raises
    ------
    ValueError
        If there are fewer than 3 averaging times or the deviations are not positive.
    """
    tau, avar = adev.tau_s, adev.adev**2
    if len(tau) < 3:
        raise ValueError(f"{len(tau)} averaging times: the noise fit needs at least 3")
    if not np.all(avar > 0):
        raise ValueError("the Allan deviation is zero at some averaging time (constant data?)")
    basis = _basis(tau)
    alpha = np.full(len(tau), ALPHA["white"])
    model = avar.copy()
    coef = np.zeros(len(TERMS))
    for _ in range(ITERATIONS):
        edf = equivalent_dof(adev.m, adev.n_phase, alpha)
        weight = np.sqrt(edf / 2.0) / model
        coef, _ = nnls(basis * weight[:, None], avar * weight)
        parts = basis * coef
        model = np.maximum(parts.sum(axis=1), np.finfo(float).tiny)
        dominant_idx = np.argmax(parts, axis=1)
        alpha = np.array([TERM_ALPHA[TERMS[i]] for i in dominant_idx])
    edf = equivalent_dof(adev.m, adev.n_phase, alpha)
    weight = np.sqrt(edf / 2.0) / model
    low, high = confidence_interval(adev.adev, edf, level)

    residual = (avar - model) * weight
    active = coef > 0
    n_free = max(len(tau) - int(active.sum()), 1)
    reduced_chi2 = float(residual @ residual / n_free)
    cov = np.zeros((len(TERMS), len(TERMS)))
    if active.any():
        a = basis[:, active] * weight[:, None]
        cov_active = np.linalg.pinv(a.T @ a)
        cov[np.ix_(active, active)] = cov_active
    dominant = tuple(TERMS[i] for i in dominant_idx)

    terms = {}
    for j, t in enumerate(TERMS):
        c, c_std = coef[j], float(np.sqrt(cov[j, j]))
        upper = float(np.sqrt(np.min(high**2 / basis[:, j]) / _FACTOR[t]))
        resolved = bool(t in dominant and c > 2.0 * c_std)
        if resolved:
            value = float(np.sqrt(c / _FACTOR[t]))
            # d sqrt(c / f) = dc / (2 sqrt(c f))
            std = c_std / (2.0 * np.sqrt(c * _FACTOR[t]))
            terms[t] = TermFit(t, value, float(std), max(upper, value), True)
        else:
            terms[t] = TermFit(t, None, None, upper, False)
    return NoiseFit(
        adev=adev,
        edf=edf,
        ci_low=low,
        ci_high=high,
        level=level,
        terms=terms,
        model_adev=np.sqrt(model),
        dominant=dominant,
        reduced_chi2=reduced_chi2,
    )
