"""Time base of the validation: module samples on the time axis, and the reference's clock.

The squared rate magnitude ``|omega|^2`` does not depend on the mounting, so the module's and
the reference's are cross-correlated (coarse lag on a common grid), then refined by non-linear
least squares with sub-sample resolution and a linear clock drift. The square, not ``|omega|``:
noise raises the mean of ``|omega|^2`` by a constant (``3 sigma^2``) that the fitted offset
absorbs, while it bends ``|omega|`` near rest, which shifts starts and stops of rotations in
opposite directions by milliseconds. Convention::

    t_ref = offset_s + (1 + drift_ppm * 1e-6) * t_module

(``offset_s`` is the offset at ``t_module = 0``; ``offset_mid_s`` the offset at the centre of
the overlap, where it is best determined).

Module samples are placed on the time axis by their packet counter (lost packets leave gaps,
rows are not assumed equally spaced).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.interpolate import BSpline, CubicSpline
from scipy.linalg import solve_banded
from scipy.optimize import least_squares

from imucal.columns import SENSOR_COLUMNS, SENSORS, SEQ, TIME
from imucal.ingest.timebase import unwrap_seq

#: The time convention of :class:`TimeAlignment`, written into the JSON result.
TIME_CONVENTION = "t_ref = offset_s + (1 + drift_ppm * 1e-6) * t_module"


# --------------------------------------------------------------------------- time axes


def packet_times(t_s: np.ndarray, seq: np.ndarray) -> np.ndarray:
    """Sample times from the packet counter: ``t = t0 + index * period``.

    ``t0`` and ``period`` are the least-squares line of the logged ``t_s`` against the unwrapped
    packet index, so timestamp jitter averages out, lost packets leave exact gaps, and the
    clock of ``t_s`` is kept (its drift against another device is estimated later).

    Parameters
    ----------
    t_s : array_like, shape (n,)
        Logged timestamps, s.
    seq : array_like of int, shape (n,)
        Packet counters (16 bit, wrapping).

    Returns
    -------
    ndarray, shape (n,)
        Sample times, s.

    Raises
    ------
    ValueError
        If the shapes differ, fewer than 2 samples are given or the timestamps are not finite.
    """
    t = np.asarray(t_s, dtype=float)
    if t.shape != np.shape(seq):
        raise ValueError(
            f"t_s has shape {t.shape} but seq has shape {np.shape(seq)}; expected equal"
        )
    if t.size < 2 or not np.all(np.isfinite(t)):
        raise ValueError(f"t_s must hold at least 2 finite timestamps, got {t.size} samples")
    index = unwrap_seq(seq, t_s=t)
    period, t0 = np.polyfit(index.astype(float), t, 1)
    if period <= 0:
        raise ValueError(
            f"t_s decreases with the packet index (period {period:.3g} s); expected > 0"
        )
    return t0 + index * period


# --------------------------------------------------------------------------- time alignment


@dataclass(frozen=True)
class TimeAlignment:
    """Clock relation ``t_ref = offset_s + (1 + drift_ppm * 1e-6) * t_module``.

    Attributes
    ----------
    offset_s, offset_std_s : float
        Offset at ``t_module = 0`` and its standard deviation, s.
    offset_mid_s, offset_mid_std_s : float
        Offset ``t_ref - t_module`` at ``t_mid_s`` (centre of the overlap) and its std, s.
    t_mid_s : float
        Module time of the centre of the overlap, s.
    drift_ppm, drift_std_ppm : float
        Rate of the reference clock relative to the module clock minus one, 1e-6.
    correlation : float
        Correlation coefficient of the module's and the aligned reference's ``|omega|^2``.
    window_t_s, window_offset_s : ndarray, shape (k,)
        Module time of the centre of each window with motion, and the offset fitted there (s).
    std_inflation : float
        Factor (>= 1) applied to the formal standard deviations, from the windows' scatter.
    n_samples : int
        Module samples used.
    """

    offset_s: float
    offset_std_s: float
    offset_mid_s: float
    offset_mid_std_s: float
    t_mid_s: float
    drift_ppm: float
    drift_std_ppm: float
    correlation: float
    window_t_s: np.ndarray
    window_offset_s: np.ndarray
    std_inflation: float
    n_samples: int

    def to_reference_time(self, t_module: np.ndarray) -> np.ndarray:
        """Reference-clock time of module times ``t_module`` (shape (n,), s)."""
        return self.offset_s + (1.0 + self.drift_ppm * 1e-6) * np.asarray(t_module, dtype=float)

    def to_dict(self) -> dict:
        return {
            "convention": TIME_CONVENTION,
            "offset_s": self.offset_s,
            "offset_std_s": self.offset_std_s,
            "offset_mid_s": self.offset_mid_s,
            "offset_mid_std_s": self.offset_mid_std_s,
            "t_mid_s": self.t_mid_s,
            "drift_ppm": self.drift_ppm,
            "drift_std_ppm": self.drift_std_ppm,
            "correlation": self.correlation,
            "windows": [
                {"t_module_s": float(t), "offset_s": float(o)}
                for t, o in zip(self.window_t_s, self.window_offset_s)
            ],
            "std_inflation": self.std_inflation,
            "n_samples": self.n_samples,
        }


def _check_series(t: np.ndarray, x: np.ndarray, name: str) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(t, dtype=float)
    x = np.asarray(x, dtype=float)
    if t.ndim != 1 or x.shape != (t.size, 3):
        raise ValueError(
            f"{name}: expected times (n,) and vectors (n, 3), got {t.shape}, {x.shape}"
        )
    if t.size < 10:
        raise ValueError(f"{name}: expected at least 10 samples, got {t.size}")
    if np.any(np.diff(t) <= 0):
        raise ValueError(f"{name}: times must increase strictly")
    return t, x


def _rate_squared(t: np.ndarray, gyr: np.ndarray, name: str) -> tuple[np.ndarray, np.ndarray]:
    t, gyr = _check_series(t, gyr, name)
    ok = np.all(np.isfinite(gyr), axis=1)
    return t[ok], np.sum(gyr[ok] ** 2, axis=1)


def _coarse_offset(t_m: np.ndarray, w_m: np.ndarray, t_r: np.ndarray, w_r: np.ndarray) -> float:
    """Offset ``t_ref - t_module`` at the peak of the overlap-normalised cross-correlation."""
    # imported here: scipy.signal (with scipy.stats) costs about 0.5 s, and the packet times
    # are all that most importers of this module use
    from scipy.signal import correlate

    dt = min(np.median(np.diff(t_m)), np.median(np.diff(t_r)))
    grid_m = np.arange(t_m[0], t_m[-1], dt)
    grid_r = np.arange(t_r[0], t_r[-1], dt)
    x = np.interp(grid_m, t_m, w_m)
    y = np.interp(grid_r, t_r, w_r)
    x = x - x.mean()
    y = y - y.mean()
    n, m = x.size, y.size
    # index k of the full correlation is the lag L = k - (n - 1): y[i + L] pairs with x[i]
    num = correlate(y, x, mode="full", method="fft")
    ex = correlate(np.ones(m), x * x, mode="full", method="fft")
    ey = correlate(y * y, np.ones(n), mode="full", method="fft")
    overlap = correlate(np.ones(m), np.ones(n), mode="full", method="fft")
    # short overlaps give spurious peaks: require half of the shorter recording
    valid = (overlap > 0.5 * min(n, m)) & (ex > 0) & (ey > 0)
    if not np.any(valid):
        raise ValueError("the recordings are too short to overlap by half of the shorter one")
    rho = np.full(num.shape, -np.inf)
    rho[valid] = num[valid] / np.sqrt(ex[valid] * ey[valid])
    k = int(np.argmax(rho))
    lag = float(k - (n - 1))
    if 0 < k < rho.size - 1 and np.isfinite(rho[k - 1]) and np.isfinite(rho[k + 1]):
        # parabolic interpolation of the peak
        denom = rho[k - 1] - 2 * rho[k] + rho[k + 1]
        if denom < 0:
            lag += 0.5 * (rho[k - 1] - rho[k + 1]) / denom
    return grid_r[0] - grid_m[0] + lag * dt


class SmoothingSplines:
    """Cubic smoothing splines through samples at fixed abscissae, for any data and parameter.

    The same problem and solution as :func:`scipy.interpolate.make_smoothing_spline` (natural
    cubic splines, the banded system of its references [4]), with what depends on the abscissae
    alone (the design and penalty bands) computed once and vectorised: a search of the smoothing
    parameter then solves one banded system per trial instead of rebuilding both bands with
    scipy's per-sample Python loop.

    Parameters
    ----------
    x : ndarray, shape (n,)
        Strictly increasing abscissae (n >= 5).
    """

    def __init__(self, x: np.ndarray) -> None:
        x = np.ascontiguousarray(x, dtype=float)
        n = x.size
        if n < 5 or np.any(np.diff(x) <= 0):
            raise ValueError(f"need >= 5 strictly increasing abscissae, got {n}")
        t = np.r_[[x[0]] * 3, x, [x[-1]] * 3]
        xb = BSpline.design_matrix(x, t, 3).tocsr()  # sparse: n x (n + 2), 4 per row
        design = np.zeros((5, n))
        idx = np.arange(n - 4)
        for i in range(1, 4):
            design[i, 2:-2] = np.asarray(xb[idx + i, idx + 3]).ravel()
        design[1, 1] = xb[0, 0]
        design[2, :2] = ((x[2] + x[1] - 2 * x[0]) * xb[0, 0], xb[1, 1] + xb[1, 2])
        design[3, :2] = ((x[2] - x[0]) * xb[1, 1], xb[2, 2])
        design[1, -2:] = (xb[-3, -3], (x[-1] - x[-3]) * xb[-2, -2])
        design[2, -2:] = (xb[-2, -3] + xb[-2, -2], (2 * x[-1] - x[-2] - x[-3]) * xb[-1, -1])
        design[3, -2] = xb[-1, -1]
        penalty = np.zeros((5, n))
        penalty[2:, 0] = _divided_difference(x[None, :3])[0]
        penalty[1:, 1] = _divided_difference(x[None, :4])[0]
        windows = np.lib.stride_tricks.sliding_window_view(x, 5)[: n - 4]
        penalty[:, 2 : n - 2] = ((windows[:, 4] - windows[:, 0])[:, None]
                                 * _divided_difference(windows)).T  # fmt: skip
        penalty[:-1, -2] = -_divided_difference(x[None, -4:])[0]
        penalty[:-2, -1] = _divided_difference(x[None, -3:])[0]
        self._t, self._design, self._penalty = t, design, 6 * penalty

    def fit(self, y: np.ndarray, lam: float) -> BSpline:
        """The smoothing spline of ``y`` (shape (n,)) with smoothing parameter ``lam`` >= 0."""
        c = solve_banded((2, 2), self._design + lam * self._penalty, np.asarray(y, float))
        t = self._t
        coef = np.r_[
            c[0] * (t[5] + t[4] - 2 * t[3]) + c[1], c[0] * (t[5] - t[3]) + c[1], c[1:-1],
            c[-1] * (t[-4] - t[-6]) + c[-2], c[-1] * (2 * t[-4] - t[-5] - t[-6]) + c[-2],
        ]  # fmt: skip
        return BSpline.construct_fast(t, coef, 3)


def _divided_difference(windows: np.ndarray) -> np.ndarray:
    """Coefficients of the divided difference over each row of ``windows`` (m, k): row-wise
    ``1 / prod_{l != i} (x_i - x_l)``, the products taken in the order of ``l``."""
    m, k = windows.shape
    out = np.ones((m, k))
    for i in range(k):
        for j in range(k):
            if j != i:
                out[:, i] *= windows[:, i] - windows[:, j]
    return 1.0 / out


#: Relative precision of the smoothing parameter of :func:`_smooth_reference`.
LAMBDA_TOLERANCE = 0.01


def _smooth_reference(t: np.ndarray, w: np.ndarray, excerpt: int = 1500) -> BSpline:
    """Smoothing spline through the reference's ``|omega|^2``.

    The fit uses the slope of the reference; an interpolating spline would differentiate the
    noise and report timing information where the platform rests. The smoothing parameter
    follows the discrepancy principle: the residual variance equals the noise variance, which
    is estimated from second differences (``var(y[i-1] - 2 y[i] + y[i+1]) = 6 sigma^2`` for
    white noise on a signal that is smooth at the sampling rate). It is searched on the
    ``excerpt`` consecutive samples of largest variance (the motion) to keep the cost low, to
    :data:`LAMBDA_TOLERANCE` in ``lam``: the noise variance that sets it is estimated from at most
    ``excerpt`` samples, uncertain by several percent.
    """
    if t.size > excerpt:
        csum = np.cumsum(np.concatenate([[0.0], w]))
        csum2 = np.cumsum(np.concatenate([[0.0], w * w]))
        mean = (csum[excerpt:] - csum[:-excerpt]) / excerpt
        var = (csum2[excerpt:] - csum2[:-excerpt]) / excerpt - mean**2
        i = int(np.argmax(var))
        ts, ws = t[i : i + excerpt], w[i : i + excerpt]
    else:
        ts, ws = t, w
    noise_var = np.mean(np.diff(ws, 2) ** 2) / 6.0
    period = np.median(np.diff(ts))
    # bisection on log(lam); lam ~ h^4 / period for an equivalent kernel of width h (s)
    lo, hi = np.log((0.1 * period) ** 4 / period), np.log(10.0**4 / period)
    splines = SmoothingSplines(ts)
    while hi - lo > np.log1p(LAMBDA_TOLERANCE):
        mid = 0.5 * (lo + hi)
        fit = splines.fit(ws, np.exp(mid))
        if np.mean((fit(ts) - ws) ** 2) > noise_var:
            hi = mid
        else:
            lo = mid
    return SmoothingSplines(t).fit(w, np.exp(lo))


def _fit_shift(
    t: np.ndarray,
    w: np.ndarray,
    spline: BSpline,
    t_mid: float,
    start: np.ndarray,
    free: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, float]:
    """Least squares ``w = a + b * spline(t_mid + offset + (1 + drift * 1e-6) (t - t_mid))``.

    ``start`` holds (a, b, offset, drift_ppm); only the entries where ``free`` is True are
    fitted. Returns all four parameters, the covariance of the free ones (scaled by the residual
    variance) and the correlation coefficient.
    """
    deriv = spline.derivative()
    dt = t - t_mid
    start = np.asarray(start, dtype=float)

    def full(q: np.ndarray) -> np.ndarray:
        p = start.copy()
        p[free] = q
        return p

    def tau(p: np.ndarray) -> np.ndarray:
        return t_mid + p[2] + (1.0 + p[3] * 1e-6) * dt

    def residual(q: np.ndarray) -> np.ndarray:
        p = full(q)
        return p[0] + p[1] * spline(tau(p)) - w

    def jacobian(q: np.ndarray) -> np.ndarray:
        p = full(q)
        ta = tau(p)
        slope = p[1] * deriv(ta)
        cols = np.column_stack([np.ones_like(t), spline(ta), slope, slope * dt * 1e-6])
        return cols[:, free]

    sol = least_squares(residual, start[free], jac=jacobian, method="lm", x_scale="jac")
    dof = max(sol.fun.size - int(free.sum()), 1)
    s2 = float(sol.fun @ sol.fun) / dof
    jac = jacobian(sol.x)
    cov = s2 * np.linalg.pinv(jac.T @ jac)
    p = full(sol.x)
    rho = float(np.corrcoef(spline(tau(p)), w)[0, 1])
    return p, cov, rho


def estimate_time_alignment(
    t_module: np.ndarray,
    gyr_module: np.ndarray,
    t_reference: np.ndarray,
    gyr_reference: np.ndarray,
    n_windows: int = 6,
    reference_max_gap_s: float | None = None,
) -> TimeAlignment:
    """Offset and drift of the reference clock against the module clock from ``|omega|^2``.

    Parameters
    ----------
    t_module : array_like, shape (n,)
        Module sample times (from :func:`packet_times`), s, strictly increasing.
    gyr_module : array_like, shape (n, 3)
        Module angular rate, rad/s (calibrated is best; the fit absorbs an affine error of
        ``|omega|^2``).
    t_reference : array_like, shape (m,)
        Reference sample times on its own clock, s, strictly increasing.
    gyr_reference : array_like, shape (m, 3)
        Reference angular rate in its own axes, rad/s.
    n_windows : int
        Number of equal windows of the overlap in which the offset is fitted alone (scale and
        drift held at the global values); their scatter calibrates the reported uncertainty.
    reference_max_gap_s : float, optional
        Reference samples further apart than this (s) bound a gap (e.g. motion-capture tracking
        lost): module samples that fall into one are left out of the fit rather than compared
        with the spline bridging it. None: the reference has no gaps.

    Returns
    -------
    TimeAlignment

    Raises
    ------
    ValueError
        On malformed input, too short an overlap, or a recording without motion.

    Notes
    -----
    The global fit ``|omega_m|^2(t) = a + b |omega_r|^2(offset + (1 + drift) t)`` uses every
    module sample at its own time and a smoothing spline through the reference, so lost packets
    need no filling. Its formal covariance assumes white residuals; the smoothed reference and
    unmodelled differences between the sensors make them coloured. The covariance is therefore
    scaled by the Birge ratio of the windowed offsets about the fitted line (``sqrt`` of their
    reduced chi-square with their formal errors, at least 1), reported as ``std_inflation``.
    """
    if n_windows < 1:
        raise ValueError(f"n_windows must be >= 1, got {n_windows}")
    t_m, w_m = _rate_squared(t_module, gyr_module, "module")
    t_r, w_r = _rate_squared(t_reference, gyr_reference, "reference")
    if np.std(w_m) == 0 or np.std(w_r) == 0:
        raise ValueError("|omega| is constant in one of the recordings; expected motion")
    coarse = _coarse_offset(t_m, w_m, t_r, w_r)
    spline = _smooth_reference(t_r, w_r)
    # keep a margin of 0.5 s inside the reference so that the drift cannot push samples out
    inside = (t_m + coarse > t_r[0] + 0.5) & (t_m + coarse < t_r[-1] - 0.5)
    if reference_max_gap_s is not None:
        right = np.clip(np.searchsorted(t_r, t_m + coarse), 1, t_r.size - 1)
        inside &= t_r[right] - t_r[right - 1] <= reference_max_gap_s
    if np.count_nonzero(inside) < 10:
        raise ValueError(
            f"the recordings overlap by {np.count_nonzero(inside)} module samples at the offset "
            f"{coarse:.3f} s; expected at least 10"
        )
    t_m, w_m = t_m[inside], w_m[inside]
    t_mid = 0.5 * (t_m[0] + t_m[-1])
    r0 = spline(t_mid + coarse + (t_m - t_mid))
    b0, a0 = np.polyfit(r0, w_m, 1)
    p, cov, rho = _fit_shift(
        t_m, w_m, spline, t_mid, np.array([a0, b0, coarse, 0.0]), np.ones(4, dtype=bool)
    )
    offset_mid, drift = float(p[2]), float(p[3])

    edges = np.linspace(t_m[0], t_m[-1], n_windows + 1)
    spread_all = np.std(w_m)
    win_t, win_off, win_std = [], [], []
    only_offset = np.array([False, False, True, False])
    for lo, hi in itertools.pairwise(edges):
        sel = (t_m >= lo) & (t_m < hi)
        # a window without motion carries no timing information
        if np.count_nonzero(sel) < 10 or np.std(w_m[sel]) < 0.1 * spread_all:
            continue
        centre = 0.5 * (lo + hi)
        guess = offset_mid + drift * 1e-6 * (centre - t_mid)
        # only the offset is free: the scale and drift of the whole overlap hold here too
        pw, cw, _ = _fit_shift(
            t_m[sel], w_m[sel], spline, centre, np.array([p[0], p[1], guess, drift]), only_offset
        )
        win_t.append(centre)
        win_off.append(float(pw[2]))
        win_std.append(float(np.sqrt(cw[0, 0])))
    win_t_a, win_off_a = np.array(win_t), np.array(win_off)
    inflation = 1.0
    if win_t_a.size >= 3:
        # Birge ratio: windows scattering about the fitted line by more than their formal
        # errors reveal coloured residuals; scale the formal errors up by that ratio
        line = offset_mid + drift * 1e-6 * (win_t_a - t_mid)
        chi2 = np.sum(((win_off_a - line) / np.array(win_std)) ** 2) / (win_t_a.size - 2)
        inflation = float(np.sqrt(max(chi2, 1.0)))
    cov = cov * inflation**2

    # offset at t_module = 0: offset_mid - drift * 1e-6 * t_mid
    g = np.array([0.0, 0.0, 1.0, -1e-6 * t_mid])
    var0 = float(g @ cov @ g)
    return TimeAlignment(
        offset_s=offset_mid - drift * 1e-6 * t_mid,
        offset_std_s=float(np.sqrt(var0)),
        offset_mid_s=offset_mid,
        offset_mid_std_s=float(np.sqrt(cov[2, 2])),
        t_mid_s=float(t_mid),
        drift_ppm=drift,
        drift_std_ppm=float(np.sqrt(cov[3, 3])),
        correlation=rho,
        window_t_s=win_t_a,
        window_offset_s=win_off_a,
        std_inflation=inflation,
        n_samples=int(t_m.size),
    )


def correlate_offsets(
    t_module: np.ndarray,
    gyr_module: np.ndarray,
    t_reference: np.ndarray,
    gyr_reference: np.ndarray,
    offsets_s: np.ndarray,
    drift_ppm: float = 0.0,
) -> np.ndarray:
    """Correlation coefficient of ``|omega|^2`` for each candidate offset (for plots and checks).

    Parameters
    ----------
    t_module, gyr_module, t_reference, gyr_reference
        As in :func:`estimate_time_alignment`.
    offsets_s : array_like, shape (k,)
        Candidate offsets at ``t_module = 0`` in the convention of :data:`TIME_CONVENTION`, s.
    drift_ppm : float
        Clock drift applied with every offset, 1e-6.

    Returns
    -------
    ndarray, shape (k,)
        Pearson correlation over the module samples inside the reference; NaN where fewer than
        10 samples overlap.
    """
    t_m, w_m = _rate_squared(t_module, gyr_module, "module")
    t_r, w_r = _rate_squared(t_reference, gyr_reference, "reference")
    spline = _smooth_reference(t_r, w_r)
    out = np.full(np.size(offsets_s), np.nan)
    for i, off in enumerate(np.atleast_1d(np.asarray(offsets_s, dtype=float))):
        tau = off + (1.0 + drift_ppm * 1e-6) * t_m
        sel = (tau >= t_r[0]) & (tau <= t_r[-1])
        if np.count_nonzero(sel) >= 10:
            out[i] = np.corrcoef(spline(tau[sel]), w_m[sel])[0, 1]
    return out


# --------------------------------------------------------------------------- resampling


def align_reference(
    reference: pd.DataFrame,
    t_module: np.ndarray,
    alignment: TimeAlignment,
    rotation: np.ndarray | None = None,
) -> pd.DataFrame:
    """The reference at the module's sample times, optionally rotated into frame B.

    Parameters
    ----------
    reference : DataFrame
        Ingested reference: ``t_s``, ``seq`` and the ``acc``/``gyr``/``mag`` columns.
    t_module : array_like, shape (n,)
        Module sample times, s.
    alignment : TimeAlignment
    rotation : array_like, shape (3, 3), optional
        ``R`` with ``v_B = R @ v_ref``; without it the vectors stay in the reference's axes.

    Returns
    -------
    DataFrame, n rows
        ``t_s`` (= ``t_module``) and the sensor columns, interpolated with a cubic spline on the
        reference's packet times; NaN where the time falls outside the reference or inside a gap
        of more than 1.5 reference periods.
    """
    t_ref = packet_times(reference[TIME].to_numpy(), reference[SEQ].to_numpy())
    tau = alignment.to_reference_time(t_module)
    period = np.median(np.diff(t_ref))
    right = np.clip(np.searchsorted(t_ref, tau), 1, t_ref.size - 1)
    gap = t_ref[right] - t_ref[right - 1]
    usable = (tau >= t_ref[0]) & (tau <= t_ref[-1]) & (gap <= 1.5 * period)
    out = {TIME: np.asarray(t_module, dtype=float)}
    for sensor in SENSORS:
        cols = SENSOR_COLUMNS[sensor]
        values = reference[list(cols)].to_numpy(dtype=float)
        ok = np.all(np.isfinite(values), axis=1)
        v = np.full((tau.size, 3), np.nan)
        if np.count_nonzero(ok) >= 4:
            v[usable] = CubicSpline(t_ref[ok], values[ok])(tau[usable])
        if rotation is not None:
            v = v @ np.asarray(rotation, dtype=float).T
        out.update(dict(zip(cols, v.T)))
    return pd.DataFrame(out)
