"""Overlapping Allan deviation of a static recording, with chi-squared confidence intervals.

The estimator is NIST SP 1065 eq. (11) on the integrated rate ("phase")
``x_k = dt * sum_{i<k} (y_i - mean(y))``:

    sigma^2(m dt) = sum_k (x_{k+2m} - 2 x_{k+m} + x_k)^2 / (2 (m dt)^2 (M - 2m)),

``M = n + 1`` phase points. ``allantools`` (PyPI) is the maintained reference implementation of
these statistics; this module uses it for what it does well and keeps only two things of its own:

* the sum above, evaluated in chunks of :data:`CHUNK` samples. ``allantools.oadev`` builds four
  temporaries of the full length per averaging time (the second difference, its square, the
  frequency-to-phase copies), some 5 N x 8 bytes per column: 350 MB for a 24 h recording at
  100 Hz, on top of the table. Here the only full-length array is the phase of the one column
  being analysed (``tests/benchmarks/noise/bench_noise.py`` measures the difference; the values
  equal ``allantools.oadev``'s to 1e-10 relative, ``tests/noise/test_allan.py``);
* nothing else: the equivalent degrees of freedom are ``allantools.edf_greenhall`` (Greenhall's
  algorithm for the overlapping Allan variance, for the noise type that dominates at each
  averaging time, chosen by :mod:`imucal.noise.fit`) and the interval is
  ``allantools.confidence_interval`` (chi-squared, NIST SP 1065 eq. 45).

References
----------
W. J. Riley, "Handbook of Frequency Stability Analysis", NIST SP 1065, 2008.
C. A. Greenhall, W. J. Riley, "Uncertainty of stability variances based on finite differences",
35th PTTI meeting, 2003.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Samples per chunk of the second-difference sum (bounds the temporaries, 8 MB each).
CHUNK = 1 << 20
#: Largest cluster size as a fraction of the samples: allantools' stop ratio for oadev
#: ("Evolution of frequency stability analysis software", Table III).
STOP_RATIO = 4
#: Power-law exponent of the rate noise's PSD, S(f) ~ f^alpha, as allantools names them.
ALPHA = {"quantisation": 2, "white": 0, "flicker": -1, "random_walk": -2}


@dataclass(frozen=True)
class AllanDeviation:
    """Overlapping Allan deviation of one axis.

    Attributes
    ----------
    tau_s : ndarray, shape (k,)
        Averaging times, s (octave-spaced multiples of the sample interval).
    m : ndarray, shape (k,)
        Cluster sizes, samples.
    adev : ndarray, shape (k,)
        Allan deviation in the unit of the samples.
    n_phase : int
        Number of phase points (samples + 1), for the degrees of freedom.
    """

    tau_s: np.ndarray
    m: np.ndarray
    adev: np.ndarray
    n_phase: int


def octave_cluster_sizes(n_samples: int) -> np.ndarray:
    """Cluster sizes 1, 2, 4, ... up to ``n_samples / STOP_RATIO``.

    Raises
    ------
    ValueError
        If the recording is too short for one cluster size (fewer than ``2 * STOP_RATIO``
        samples).
    """
    if n_samples < 2 * STOP_RATIO:
        raise ValueError(
            f"{n_samples} samples: the Allan deviation needs at least {2 * STOP_RATIO}"
        )
    top = int(np.floor(np.log2(n_samples / STOP_RATIO)))
    return 2 ** np.arange(top + 1, dtype=np.int64)


def integrate_rate(y: np.ndarray, rate_hz: float) -> np.ndarray:
    """Phase ``x`` of the rate samples ``y``: the mean removed, integrated, ``x[0] = 0``.

    The mean is removed first (as allantools does) so that the second differences of a
    signal on a large offset (gravity on one accelerometer axis) keep their precision.

    Parameters
    ----------
    y : ndarray, shape (n,)
        Rate samples at ``rate_hz``, any unit U.
    rate_hz : float

    Returns
    -------
    ndarray, shape (n + 1,)
        Integrated samples, U s.
    """
    x = np.empty(len(y) + 1)
    x[0] = 0.0
    np.subtract(y, np.mean(y), out=x[1:])
    np.cumsum(x[1:], out=x[1:])
    x[1:] *= 1.0 / rate_hz
    return x


def overlapping_adev(y: np.ndarray, rate_hz: float, m: np.ndarray | None = None) -> AllanDeviation:
    """Overlapping Allan deviation of one axis, evaluated in bounded memory.

    Parameters
    ----------
    y : ndarray, shape (n,)
        Equally spaced rate samples (e.g. rad/s), finite.
    rate_hz : float
        Sample rate, Hz.
    m : ndarray of int, shape (k,), optional
        Cluster sizes; by default :func:`octave_cluster_sizes`.

    Returns
    -------
    AllanDeviation

    Raises
    ------
    ValueError
        If ``y`` holds non-finite values, ``rate_hz`` is not positive or the recording is too
        short.
    """
    y = np.asarray(y, dtype=float)
    if y.ndim != 1 or not np.all(np.isfinite(y)):
        raise ValueError(f"rate samples must be one finite column, got shape {y.shape}")
    if not rate_hz > 0:
        raise ValueError(f"rate_hz must be positive, got {rate_hz!r}")
    m = octave_cluster_sizes(len(y)) if m is None else np.asarray(m, dtype=np.int64)
    x = integrate_rate(y, rate_hz)
    adev = np.array([_adev_at(x, int(mj), rate_hz) for mj in m])
    return AllanDeviation(tau_s=m / rate_hz, m=m, adev=adev, n_phase=len(x))


def _adev_at(x: np.ndarray, m: int, rate_hz: float) -> float:
    """sqrt(sum (x[k+2m] - 2 x[k+m] + x[k])^2 / (2 n (m / rate)^2)), summed chunk by chunk."""
    n = len(x) - 2 * m
    if n < 1:
        raise ValueError(f"cluster size {m} needs more than {2 * m} phase points, got {len(x)}")
    total = 0.0
    for start in range(0, n, CHUNK):
        stop = min(start + CHUNK, n)
        d = x[start + 2 * m : stop + 2 * m] - 2.0 * x[start + m : stop + m]
        d += x[start:stop]
        total += float(np.dot(d, d))
    return float(np.sqrt(total / (2.0 * n)) / m * rate_hz)


def equivalent_dof(m: np.ndarray, n_phase: int, alpha: np.ndarray) -> np.ndarray:
    """Equivalent degrees of freedom of the overlapping Allan variance (Greenhall).

    Parameters
    ----------
    m : ndarray of int, shape (k,)
        Cluster sizes.
    n_phase : int
        Number of phase points.
    alpha : ndarray of int, shape (k,)
        Noise type at each cluster size, values of :data:`ALPHA`.

    Returns
    -------
    ndarray, shape (k,)
    """
    # imported here: allantools (with scipy.stats and scipy.signal) costs about 1 s, and the
    # readers of a noise artifact (the exports) need none of it
    import allantools

    return np.array(
        [
            allantools.edf_greenhall(
                alpha=int(a), d=2, m=int(mj), N=int(n_phase), overlapping=True, modified=False
            )
            for mj, a in zip(m, alpha)
        ]
    )


def confidence_interval(
    adev: np.ndarray, edf: np.ndarray, level: float
) -> tuple[np.ndarray, np.ndarray]:
    """Chi-squared interval of each deviation at two-sided ``level`` (e.g. 0.683).

    Returns
    -------
    low, high : ndarray, shape (k,)
        Bounds of the Allan deviation, in its unit.
    """
    if not 0 < level < 1:
        raise ValueError(f"confidence level must be in (0, 1), got {level!r}")
    import allantools

    bounds = [allantools.confidence_interval(d, e, ci=level) for d, e in zip(adev, edf)]
    low, high = (np.array(b) for b in zip(*bounds)) if bounds else (np.array([]), np.array([]))
    return low, high
