"""Validation against a factory-calibrated reference IMU (Xsens MTx), as in Fig. 20 of the paper.

The reference rides on the platform with the module but has its own clock and its own axes.
Three steps bring it into the module's frame B and time base:

1. **Time alignment.** The squared rate magnitude ``|omega|^2`` does not depend on the mounting,
   so the module's and the reference's are cross-correlated (coarse lag on a common grid), then
   refined by non-linear least squares with sub-sample resolution and a linear clock drift.
   The square, not ``|omega|``: noise raises the mean of ``|omega|^2`` by a constant (``3
   sigma^2``) that the fitted offset absorbs, while it bends ``|omega|`` near rest, which
   shifts starts and stops of rotations in opposite directions by milliseconds.
   Convention::

       t_ref = offset_s + (1 + drift_ppm * 1e-6) * t_module

   (``offset_s`` is the offset at ``t_module = 0``; ``offset_mid_s`` the offset at the centre of
   the overlap, where it is best determined).
2. **Mounting.** The rotation ``R`` with ``v_B = R @ v_ref`` from the time-aligned gyroscope and
   accelerometer vectors (weighted Wahba problem, solved with an SVD).
3. **Metrics** of the module before and after calibration against the aligned reference: the
   RMS of ``|module| - |reference|`` (Fig. 20), the RMS per axis, the angle between the vectors,
   and the reference-free dip-angle consistency in static poses.

Module samples are placed on the time axis by their packet counter (lost packets leave gaps,
rows are not assumed equally spaced). The magnetometer of the module (10 Hz) is compared only at
its own sample times; its missing rows are never filled.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.interpolate import BSpline, CubicSpline, make_smoothing_spline
from scipy.optimize import least_squares
from scipy.signal import correlate
from scipy.spatial.transform import Rotation

from imucal.columns import ACC, GYR, MAG, SENSOR_COLUMNS, SENSORS, SEQ, SEQ_MODULUS, TIME
from imucal.timebase import unwrap_counter

#: The time convention of :class:`TimeAlignment`, written into the JSON result.
TIME_CONVENTION = "t_ref = offset_s + (1 + drift_ppm * 1e-6) * t_module"
#: The mounting convention of :class:`Mounting`, written into the JSON result.
MOUNTING_CONVENTION = "v_B = R @ v_ref; R = Rotation.from_rotvec(rotvec_rad)"

NO_REFERENCE_NOTE = (
    "no reference recording: only the reference-free checks (dip-angle consistency) are reported"
)


# --------------------------------------------------------------------------- time axes


def unwrap_seq(
    seq: np.ndarray, modulus: int = SEQ_MODULUS, t_s: np.ndarray | None = None
) -> np.ndarray:
    """Packet index from a wrapping packet counter (:func:`imucal.timebase.unwrap_counter`).

    Parameters
    ----------
    seq : array_like of int, shape (n,)
        Received packet counters in order of reception, counting modulo ``modulus``.
    modulus : int
        Counter period (65536 for a 16-bit counter).
    t_s : array_like, shape (n,), optional
        Receiver times, s; with them a silence longer than a wrap is counted from the time.

    Returns
    -------
    ndarray of int64, shape (n,)
        Index of each packet counted from the first received one (0); lost packets leave gaps.

    Raises
    ------
    ValueError
        If ``seq`` is empty, not one-dimensional, or repeats a counter value (difference 0).

    Notes
    -----
    Without ``t_s`` a loss of ``modulus / 2`` or more consecutive packets cannot be told from a
    counter going back.
    """
    s = np.asarray(seq)
    if s.ndim != 1 or s.size == 0:
        raise ValueError(f"seq must be a non-empty 1-D array, got shape {s.shape}")
    step = np.mod(np.diff(s.astype(np.int64)), modulus)
    if np.any(step == 0):
        first = int(np.flatnonzero(step == 0)[0])
        raise ValueError(
            f"seq repeats the value {int(s[first])} at rows {first} and {first + 1}; "
            "expected a strictly advancing packet counter"
        )
    index = unwrap_counter(s, modulus, t_s)
    return index - index[0]


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


def _smooth_reference(t: np.ndarray, w: np.ndarray, excerpt: int = 1500) -> BSpline:
    """Smoothing spline through the reference's ``|omega|^2``.

    The fit uses the slope of the reference; an interpolating spline would differentiate the
    noise and report timing information where the platform rests. The smoothing parameter
    follows the discrepancy principle: the residual variance equals the noise variance, which
    is estimated from second differences (``var(y[i-1] - 2 y[i] + y[i+1]) = 6 sigma^2`` for
    white noise on a signal that is smooth at the sampling rate). It is searched on the
    ``excerpt`` consecutive samples of largest variance (the motion) to keep the cost low.
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
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        fit = make_smoothing_spline(ts, ws, lam=np.exp(mid))
        if np.mean((fit(ts) - ws) ** 2) > noise_var:
            hi = mid
        else:
            lo = mid
    return make_smoothing_spline(t, w, lam=np.exp(lo))


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


# --------------------------------------------------------------------------- mounting


@dataclass(frozen=True)
class Mounting:
    """Rotation from the reference's axes to frame B: ``v_B = matrix @ v_ref``.

    Attributes
    ----------
    matrix : ndarray, shape (3, 3)
    rotvec_rad : ndarray, shape (3,)
    angle_deg, angle_std_deg : float
        Rotation angle and the RMS uncertainty of the rotation vector (formal, white residuals).
    residual_rms : dict
        Per sensor ('acc', 'gyr'): RMS per component of ``v_B - R v_ref`` (m/s^2, rad/s).
    n_samples : dict
        Per sensor: vector pairs used.
    """

    matrix: np.ndarray
    rotvec_rad: np.ndarray
    angle_deg: float
    angle_std_deg: float
    residual_rms: dict
    n_samples: dict

    def to_dict(self) -> dict:
        return {
            "convention": MOUNTING_CONVENTION,
            "matrix": self.matrix.tolist(),
            "rotvec_rad": self.rotvec_rad.tolist(),
            "angle_deg": self.angle_deg,
            "angle_std_deg": self.angle_std_deg,
            "residual_rms": dict(self.residual_rms),
            "n_samples": dict(self.n_samples),
        }


def _wahba(b: np.ndarray, r: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Rotation R minimising sum w |b - R r|^2 (Kabsch / Markley SVD)."""
    h = (b * w[:, None]).T @ r
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(u @ vt))
    return u @ np.diag([1.0, 1.0, d]) @ vt


def estimate_mounting(
    vectors_module: dict[str, np.ndarray], vectors_reference: dict[str, np.ndarray]
) -> Mounting:
    """Mounting rotation from time-aligned vector pairs (weighted Wahba problem).

    Parameters
    ----------
    vectors_module : dict of str to ndarray, shape (n_s, 3)
        Calibrated module vectors in frame B per sensor (e.g. 'acc' in m/s^2, 'gyr' in rad/s).
    vectors_reference : dict of str to ndarray, shape (n_s, 3)
        The reference vectors at the same times, in the reference's axes, same keys.
        Rows with a NaN in either are dropped.

    Returns
    -------
    Mounting

    Raises
    ------
    ValueError
        If the keys or shapes differ, or fewer than 2 non-parallel vectors remain.

    Notes
    -----
    Each sensor is weighted by the inverse variance of its own residual, ``1 / sigma_s^2``,
    which is the maximum-likelihood weighting for isotropic Gaussian residuals. The first pass
    weights each sensor by the inverse of its mean squared norm (equal shares); the second pass
    uses the residuals of the first. ``angle_std_deg`` is ``sqrt(trace(cov))`` of the rotation
    vector with ``cov = (sum_i w_i (|v_i|^2 I - v_i v_i^T))^-1``.
    """
    if set(vectors_module) != set(vectors_reference) or not vectors_module:
        raise ValueError(
            f"module sensors {sorted(vectors_module)} and reference sensors "
            f"{sorted(vectors_reference)} must be the same non-empty set"
        )
    pairs = {}
    for s, values in vectors_module.items():
        b = np.asarray(values, dtype=float)
        r = np.asarray(vectors_reference[s], dtype=float)
        if b.shape != r.shape or b.ndim != 2 or b.shape[1] != 3:
            raise ValueError(
                f"{s}: expected two (n, 3) arrays of equal shape, got {b.shape}, {r.shape}"
            )
        ok = np.all(np.isfinite(b), axis=1) & np.all(np.isfinite(r), axis=1)
        if np.count_nonzero(ok):
            pairs[s] = (b[ok], r[ok])
    if sum(len(b) for b, _ in pairs.values()) < 2:
        raise ValueError("fewer than 2 finite vector pairs; expected enough to fix a rotation")
    weight = {s: 1.0 / np.mean(np.sum(r * r, axis=1)) for s, (_, r) in pairs.items()}
    for _ in range(2):
        b_all = np.vstack([b for b, _ in pairs.values()])
        r_all = np.vstack([r for _, r in pairs.values()])
        w_all = np.concatenate([np.full(len(b), weight[s]) for s, (b, _) in pairs.items()])
        rot = _wahba(b_all, r_all, w_all)
        rms = {s: float(np.sqrt(np.mean((b - r @ rot.T) ** 2))) for s, (b, r) in pairs.items()}
        weight = {s: 1.0 / max(rms[s], 1e-12) ** 2 for s in pairs}
    v = r_all @ rot.T
    info = np.zeros((3, 3))
    for s, (_, r) in pairs.items():
        vs = r @ rot.T
        info += weight[s] * (np.sum(vs * vs) * np.eye(3) - vs.T @ vs)
    if np.linalg.matrix_rank(info) < 3 or v.shape[0] < 2:
        raise ValueError("the vector pairs are all parallel; the mounting is not observable")
    cov = np.linalg.inv(info)
    rotvec = Rotation.from_matrix(rot).as_rotvec()
    return Mounting(
        matrix=rot,
        rotvec_rad=rotvec,
        angle_deg=float(np.degrees(np.linalg.norm(rotvec))),
        angle_std_deg=float(np.degrees(np.sqrt(np.trace(cov)))),
        residual_rms=rms,
        n_samples={s: len(b) for s, (b, _) in pairs.items()},
    )


# --------------------------------------------------------------------------- metrics


def angles_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle between row vectors of ``a`` and ``b`` (shape (n, 3) each), degrees, shape (n,)."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    # atan2 of |a x b| and a.b is accurate for small angles, unlike arccos
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.sum(a * b, axis=1)))


def compare_vectors(module: np.ndarray, reference: np.ndarray, min_norm: float = 0.0) -> dict:
    """Agreement of module vectors with reference vectors in the same frame and at the same times.

    Parameters
    ----------
    module, reference : array_like, shape (n, 3)
        Rows with a NaN in either are skipped (e.g. the module magnetometer between its samples).
    min_norm : float
        The angle is averaged only over rows with ``|reference| > min_norm`` (a rate near zero
        has no direction), in the unit of the vectors.

    Returns
    -------
    dict
        ``n``; ``rms_norm_diff`` (RMS of ``|module| - |reference|``, Fig. 20), ``mean_norm_diff``;
        ``rms_axis`` (3, RMS per axis of the difference); ``rms_diff`` (RMS of ``|module -
        reference|``); ``n_angle``, ``mean_angle_deg``, ``rms_angle_deg``. Units of the vectors;
        NaN where no row qualifies.
    """
    m = np.asarray(module, dtype=float)
    r = np.asarray(reference, dtype=float)
    if m.shape != r.shape or m.ndim != 2 or m.shape[1] != 3:
        raise ValueError(f"expected two (n, 3) arrays of equal shape, got {m.shape}, {r.shape}")
    ok = np.all(np.isfinite(m), axis=1) & np.all(np.isfinite(r), axis=1)
    m, r = m[ok], r[ok]
    norm_diff = np.linalg.norm(m, axis=1) - np.linalg.norm(r, axis=1)
    diff = m - r
    directed = np.linalg.norm(r, axis=1) > min_norm
    ang = angles_deg(m[directed], r[directed])

    def rms(x: np.ndarray, axis: int | None = None) -> np.ndarray | float:
        return np.sqrt(np.mean(x**2, axis=axis)) if x.size else np.nan

    return {
        "n": int(ok.sum()),
        "rms_norm_diff": float(rms(norm_diff)),
        "mean_norm_diff": float(np.mean(norm_diff)) if norm_diff.size else np.nan,
        "rms_axis": np.asarray(rms(diff, axis=0) if diff.size else [np.nan] * 3).tolist(),
        "rms_diff": float(rms(np.linalg.norm(diff, axis=1))),
        "n_angle": int(directed.sum()),
        "mean_angle_deg": float(np.mean(ang)) if ang.size else np.nan,
        "rms_angle_deg": float(rms(ang)),
    }


def summarise_dip(acc: np.ndarray, mag: np.ndarray, mask: np.ndarray) -> dict:
    """Angle between specific force and magnetic field over the masked rows.

    In static poses gravity and the Earth's field keep a fixed angle (90 deg minus the dip
    angle) whatever the orientation, so its scatter measures the relative calibration of the
    accelerometer and the magnetometer without any reference.

    Parameters
    ----------
    acc : array_like, shape (n, 3)
        Specific force, m/s^2.
    mag : array_like, shape (n, 3)
        Magnetic field; NaN rows (no fresh sample) are skipped.
    mask : array_like of bool, shape (n,)
        Rows to use (static samples).

    Returns
    -------
    dict
        ``n``, ``mean_deg``, ``std_deg`` (NaN when fewer than 2 rows qualify).
    """
    acc = np.asarray(acc, dtype=float)
    mag = np.asarray(mag, dtype=float)
    mask = np.asarray(mask, dtype=bool)
    if acc.shape != mag.shape or mask.shape != acc.shape[:1]:
        raise ValueError(
            f"expected acc (n, 3), mag (n, 3) and mask (n,), got {acc.shape}, {mag.shape}, "
            f"{mask.shape}"
        )
    ok = mask & np.all(np.isfinite(acc), axis=1) & np.all(np.isfinite(mag), axis=1)
    ang = angles_deg(acc[ok], mag[ok])
    return {
        "n": int(ok.sum()),
        "mean_deg": float(np.mean(ang)) if ang.size >= 2 else np.nan,
        "std_deg": float(np.std(ang, ddof=1)) if ang.size >= 2 else np.nan,
    }


# --------------------------------------------------------------------------- entry point


def _vectors(table: pd.DataFrame, sensor: str) -> np.ndarray:
    return table[list(SENSOR_COLUMNS[sensor])].to_numpy(dtype=float)


def _check_table(table: pd.DataFrame, name: str) -> None:
    missing = [c for c in (TIME, SEQ, *ACC, *GYR, *MAG) if c not in table.columns]
    if missing:
        raise ValueError(f"{name} lacks the columns {missing}")


def _jsonable(x: object) -> object:
    """Floats as Python floats, NaN/inf as None, recursively."""
    if isinstance(x, dict):
        return {k: _jsonable(v) for k, v in x.items()}
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (float, np.floating)):
        return float(x) if np.isfinite(x) else None
    if isinstance(x, np.integer):
        return int(x)
    return x


def validate(
    module: pd.DataFrame,
    module_raw: pd.DataFrame,
    reference: pd.DataFrame | None,
    static_mask: np.ndarray,
    min_rate_rad_s: float = 0.2,
    n_windows: int = 6,
) -> dict:
    """Validate a calibration on the rotation3d recording against the reference IMU.

    Parameters
    ----------
    module : DataFrame
        The module's rotation3d recording, calibrated (frame B, SI units): ``t_s``, ``seq``,
        ``acc_*`` (m/s^2), ``gyr_*`` (rad/s), ``mag_*`` (normalised, NaN between samples).
    module_raw : DataFrame
        The same rows before calibration (readings = counts * sensitivity).
    reference : DataFrame or None
        The ingested reference (its own axes and clock, SI units), or None.
    static_mask : array_like of bool, shape (n,)
        Static rows of the module recording (for the dip-angle check).
    min_rate_rad_s : float
        Gyroscope angles are averaged only where the reference rate exceeds this, rad/s.
    n_windows : int
        Windows for the offset scatter, see :func:`estimate_time_alignment`.

    Returns
    -------
    dict
        JSON-ready (NaN as None): ``reference`` (None, or the number of reference samples),
        ``note``, ``dip`` (``raw``, ``calibrated`` and, with a reference, ``reference``:
        see :func:`summarise_dip`), ``time_alignment`` (:meth:`TimeAlignment.to_dict`),
        ``mounting`` (:meth:`Mounting.to_dict`), ``metrics`` (``raw`` and ``calibrated``, per
        sensor :func:`compare_vectors` in frame B with the reference time-aligned and rotated).
        The last three are None without a reference.

    Raises
    ------
    ValueError
        If a table lacks a column, the two module tables differ in ``t_s``/``seq``, or the
        mask has the wrong length.
    """
    _check_table(module, "module")
    _check_table(module_raw, "module_raw")
    if len(module) != len(module_raw) or not (
        np.array_equal(module[SEQ].to_numpy(), module_raw[SEQ].to_numpy())
        and np.allclose(module[TIME].to_numpy(), module_raw[TIME].to_numpy())
    ):
        raise ValueError(
            f"module ({len(module)} rows) and module_raw ({len(module_raw)} rows) must hold the "
            "same rows (equal t_s and seq)"
        )
    mask = np.asarray(static_mask, dtype=bool)
    if mask.shape != (len(module),):
        raise ValueError(f"static_mask has shape {mask.shape}; expected ({len(module)},)")

    dip = {
        "raw": summarise_dip(_vectors(module_raw, "acc"), _vectors(module_raw, "mag"), mask),
        "calibrated": summarise_dip(_vectors(module, "acc"), _vectors(module, "mag"), mask),
    }
    result: dict = {
        "reference": None,
        "note": NO_REFERENCE_NOTE,
        "dip": dip,
        "time_alignment": None,
        "mounting": None,
        "metrics": None,
    }
    if reference is None:
        return _jsonable(result)

    _check_table(reference, "reference")
    t_mod = packet_times(module[TIME].to_numpy(), module[SEQ].to_numpy())
    t_ref = packet_times(reference[TIME].to_numpy(), reference[SEQ].to_numpy())
    alignment = estimate_time_alignment(
        t_mod, _vectors(module, "gyr"), t_ref, _vectors(reference, "gyr"), n_windows
    )
    ref_axes = align_reference(reference, t_mod, alignment)
    mounting = estimate_mounting(
        {s: _vectors(module, s) for s in ("acc", "gyr")},
        {s: _vectors(ref_axes, s) for s in ("acc", "gyr")},
    )
    ref_b = align_reference(reference, t_mod, alignment, mounting.matrix)
    min_norm = {"acc": 0.0, "gyr": min_rate_rad_s, "mag": 0.0}
    metrics = {
        name: {
            s: compare_vectors(_vectors(table, s), _vectors(ref_b, s), min_norm[s]) for s in SENSORS
        }
        for name, table in (("raw", module_raw), ("calibrated", module))
    }
    # the reference at the same static rows where the module has a magnetometer sample
    module_mag_rows = np.all(np.isfinite(_vectors(module, "mag")), axis=1)
    dip["reference"] = summarise_dip(
        _vectors(ref_b, "acc"), _vectors(ref_b, "mag"), mask & module_mag_rows
    )
    result.update(
        reference=len(reference),
        note="module and reference compared in frame B after time alignment and mounting",
        time_alignment=alignment.to_dict(),
        mounting=mounting.to_dict(),
        metrics=metrics,
    )
    return _jsonable(result)
