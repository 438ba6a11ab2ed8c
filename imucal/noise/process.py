"""The noise of a session as a process a twin can draw: white noise, a correlated bias and a bias
random walk per axis, measured on the session's own rest, plus its quantisation step.

A twin that replays a real recording with white noise alone opens a gap wherever the real noise
is coloured: the Allan deviation at long averaging times, the trend over the recording, the
residual against a reference averaged over intervals. :func:`fit_noise_process` measures the
terms a twin needs from a rest of the recording (a static recording, or the rests of a moving
one):

* white noise per axis from first differences, with the quantisation of the readings taken out
  exactly (:func:`dither_std`: the rounding of a signal whose noise is below one count is not
  the uniform ``step^2 / 12`` a larger noise gives);
* bias instability ``B`` and rate random walk ``K`` from the IEEE Std 952 fit of the axis's
  Allan deviation (:func:`imucal.noise.fit.fit_noise_terms`), its coefficients whether or not
  the fit resolves them at two standard errors (the twin is to show the Allan deviation the
  recording shows, not only its significant terms). The flicker floor of ``B`` is drawn as a
  first-order Gauss-Markov bias whose Allan deviation peaks at the floor's level
  (``0.62 gm = sqrt(2 ln 2 / pi) B``) at the averaging time where ``B`` has its largest share
  of the fit (the peak lies at ``1.89`` correlation times); ``K`` is drawn as a random walk of
  the bias, ``K sqrt(dt)`` per sample.

:meth:`NoiseProcess.draw` renders the three terms for ``n`` samples at a rate; quantisation is
left to the renderer (it rounds the readings to counts of ``step``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats
from scipy.optimize import brentq
from scipy.signal import lfilter

from imucal.noise.allan import overlapping_adev
from imucal.noise.fit import FLICKER_FLOOR, TERMS, fit_noise_terms, term_adev

#: Allan deviation peak of a first-order Gauss-Markov process per unit std (its averaging time
#: is :data:`GM_PEAK_TAU` correlation times).
GM_PEAK = 0.62
GM_PEAK_TAU = 1.89
#: Confidence level of the noise fit's resolution test.
FIT_LEVEL = 0.9
#: Fewest rest samples for the Allan fit (shorter rests give white noise only).
MIN_FIT_SAMPLES = 1000
#: Grid of offsets within a count over which the rounding's variance is averaged.
_OFFSETS = np.linspace(0.0, 1.0, 32, endpoint=False)


def quantised_variance(std: float, step: float, level: float | None = None) -> float:
    """Variance of ``step * round(u + e / step)``, ``u = level / step``, or averaged over
    offsets ``u`` in one count when no level is given.

    Parameters
    ----------
    std : float
        White-noise std before rounding (SI).
    step : float
        Quantisation step (SI per count), > 0.
    level : float, optional
        The noise-free reading (SI).

    Returns
    -------
    float
        SI^2. Tends to ``std^2 + step^2 / 12`` for ``std`` above ``step``, to 0 for ``std``
        far below it (a constant reading), with the rounding's flips in between.
    """
    s = std / step
    if s > 3:  # the rounding error is uniform and independent of the value
        return std**2 + step**2 / 12
    if s <= 0:
        return 0.0
    half = int(np.ceil(6 * s)) + 2
    k = np.arange(-half, half + 1)[None, :]
    u = _OFFSETS[:, None] if level is None else np.array([[level / step - np.rint(level / step)]])
    p = stats.norm.cdf((k + 0.5 - u) / s) - stats.norm.cdf((k - 0.5 - u) / s)
    mean = np.sum(k * p, axis=1)
    var = np.sum(k**2 * p, axis=1) - mean**2
    return float(np.mean(var)) * step**2


def dither_std(white_variance: float, step: float, level: float | None = None) -> float:
    """White-noise std before rounding whose rounded readings have ``white_variance``.

    Parameters
    ----------
    white_variance : float
        Variance of the rounded readings' white part (half the variance of their first
        differences), SI^2.
    step : float
        Quantisation step (SI per count); 0 for readings that are not rounded.
    level : float, optional
        The reading the noise is about (SI), e.g. the mean of a rest: its offset within a
        count sets how often a small noise flips the count. Averaged over the offsets when
        not given.

    Returns
    -------
    float
        SI; 0 when the readings never change.
    """
    if white_variance <= 0:
        return 0.0
    if step <= 0:
        return float(np.sqrt(white_variance))
    if white_variance >= quantised_variance(3.0 * step, step, level):
        return float(np.sqrt(max(white_variance - step**2 / 12, 0.0)))
    if level is None:  # averaged over the offsets, the variance grows with the std
        return float(
            brentq(
                lambda s: quantised_variance(s, step) - white_variance,
                0.0,
                3.0 * step,
                xtol=1e-6 * step,
            )
        )
    # at one offset it need not (half a count off, the smallest noise flips half the
    # samples): the smallest std that reaches the variance, on a grid fine to 1 %
    grid = step * np.geomspace(1e-3, 3.0, 800)
    reached = np.array([quantised_variance(s, step, level) for s in grid]) >= white_variance
    return float(grid[np.argmax(reached)])


@dataclass(frozen=True)
class NoiseProcess:
    """The noise of one tri-axial sensor, per axis (module docstring).

    Attributes
    ----------
    white : ndarray, shape (3,)
        White-noise std per sample before rounding (SI).
    markov : ndarray, shape (3,)
        Gauss-Markov bias std (SI), the stand-in for bias instability.
    tau_s : ndarray, shape (3,)
        Its correlation time (s).
    walk : ndarray, shape (3,)
        Rate random walk ``K`` (SI / sqrt(s)).
    step : float
        Quantisation step of the readings (SI per count).
    """

    white: np.ndarray
    markov: np.ndarray
    tau_s: np.ndarray
    walk: np.ndarray
    step: float

    def draw(self, n: int, rate_hz: float, rng: np.random.Generator) -> np.ndarray:
        """White noise plus the bias processes for ``n`` samples at ``rate_hz``, shape (n, 3)
        (SI, before rounding)."""
        dt = 1.0 / rate_hz
        e = rng.standard_normal((3, n, 3))
        out = e[0] * self.white
        if np.any(self.walk > 0):
            out += np.cumsum(e[1], axis=0) * self.walk * np.sqrt(dt)
        for j in np.flatnonzero(self.markov > 0):
            a = np.exp(-dt / self.tau_s[j])
            g0 = self.markov[j] * e[2, 0, j]
            b = lfilter([self.markov[j] * np.sqrt(1 - a**2)], [1.0, -a], e[2, 1:, j], zi=[a * g0])[
                0
            ]
            out[:, j] += np.concatenate([[g0], b])
        return out

    def describe(self) -> dict:
        """JSON-ready summary (SI)."""
        return {
            "white": self.white.tolist(),
            "markov": self.markov.tolist(),
            "tau_s": self.tau_s.tolist(),
            "walk": self.walk.tolist(),
            "step": self.step,
        }


def white_process(white: float, step: float) -> NoiseProcess:
    """A process of white noise alone, the same std on every axis."""
    zero = np.zeros(3)
    return NoiseProcess(np.full(3, float(white)), zero, np.ones(3), zero.copy(), float(step))


def fit_noise_process(
    rest: np.ndarray,
    rate_hz: float,
    step: float,
    white_rests: list | None = None,
    level: np.ndarray | None = None,
) -> NoiseProcess:
    """The noise process of a sensor from a rest of its recording.

    Parameters
    ----------
    rest : ndarray, shape (n, 3)
        Readings at rest, evenly sampled (SI), for the Allan fit.
    rate_hz : float
        Their sample rate (Hz).
    step : float
        Quantisation step (SI per count); 0 when the readings are not rounded.
    white_rests : list of ndarray, optional
        Rests (each shape (k, 3)) the white noise is measured on; default ``[rest]``.
    level : ndarray, shape (3,), optional
        The reading the twin renders the noise about (SI), when it renders the rest's own
        level: the rounding is then taken out at that offset (:func:`dither_std`).

    Returns
    -------
    NoiseProcess

    Raises
    ------
    ValueError
        If ``rest`` is not (n, 3) with n >= 2 or holds non-finite values.
    """
    rest = np.asarray(rest, dtype=float)
    if rest.ndim != 2 or rest.shape[1] != 3 or len(rest) < 2 or not np.all(np.isfinite(rest)):
        raise ValueError(f"a rest must be finite readings of shape (n >= 2, 3), got {rest.shape}")
    parts = [np.asarray(p, dtype=float) for p in (white_rests or [rest]) if len(p) >= 2]
    diffs = np.vstack([np.diff(p, axis=0) for p in parts])
    levels = [None] * 3 if level is None else list(level)
    white = np.array(
        [dither_std(v / 2.0, step, u) for v, u in zip(np.var(diffs, axis=0), levels, strict=True)]
    )
    markov, tau, walk = np.zeros(3), np.ones(3), np.zeros(3)
    if len(rest) >= MIN_FIT_SAMPLES:
        for j in range(3):
            if np.ptp(rest[:, j]) <= 0:
                continue
            fit = fit_noise_terms(overlapping_adev(rest[:, j], rate_hz), level=FIT_LEVEL)
            # the fit's own coefficients, resolved or not: the twin is to show the Allan
            # deviation the recording shows (the model is linear in them, so they are exact)
            t = fit.adev.tau_s
            basis = np.column_stack([term_adev(term, 1.0, t) ** 2 for term in TERMS])
            coef = np.maximum(np.linalg.lstsq(basis, fit.model_adev**2, rcond=None)[0], 0.0)
            b, k = np.sqrt(coef[TERMS.index("B")]), np.sqrt(coef[TERMS.index("K")])
            if b > 0:
                markov[j] = FLICKER_FLOOR * b / GM_PEAK
                share = basis[:, TERMS.index("B")] * coef[TERMS.index("B")] / fit.model_adev**2
                tau[j] = float(t[np.argmax(share)]) / GM_PEAK_TAU
            walk[j] = k
    return NoiseProcess(white, markov, tau, walk, float(step))
