"""The static detector: quiet windows, static intervals at the rest level, and the motions
between them, from the raw accelerometer and gyroscope of one recording.

The paper (Zhang et al. 2014) segments by hand; the rules here are the implementer's. The
protocol segmenters (:mod:`imucal.segments.protocol`, :mod:`imucal.segments.ratetable`) and the
hand-held holds (:mod:`imucal.segments.holds`) build on it.

**Quiet windows.** The moving variance of each axis over windows of ``window_s`` is compared
with a threshold taken from the data: for white noise of variance ``s^2`` the variance ``v`` of
a window of ``n`` samples follows ``s^2 chi2(n - 1) / (n - 1)``. The noise variance of each axis
is estimated from the 10 % quantile of the window variances (the quietest windows are static or
constant-rate in every protocol recording; windows constant on the axis, clipped at the range,
are left out) divided by the same quantile of ``chi2(n-1)/(n-1)``,
then refined once as the median variance of the windows found quiet. A window is quiet when
every axis stays below the ``1 - p_false`` quantile of that distribution (``p_false = 1e-6``:
~2.3 s^2 for 0.5 s at 100 Hz). The estimate is floored at the quantisation variance
``step^2 / 12`` (``step`` the smallest difference between readings). A sample is quiet when some
quiet window contains it, so a quiet interval ends where the motion becomes visible.

**Static intervals** are quiet in both the gyroscope and the accelerometer, last at least
``min_static_s``, and have a mean raw rate at the *rest level*, the gyro bias. The bias of a
consumer part is large (an MPU-6050's zero-rate output is specified to +-20 deg/s) and moves
during a session (warm-up 0.1-0.25 deg/s/K, random walk), so the rest level is neither zero,
nor the smallest mean rate, nor one constant. It is found as the longest *chain* of quiet
intervals in time order whose consecutive mean rates differ by at most ``rest_tol_dps`` plus
``rest_drift_dps_per_s`` times the time between them: every quiet interval seeds a chain, the
chain is grown forwards and backwards from it, and the chain with the largest total duration is
the rest (the protocols rest most of the time; a slow handling motion or a constant-rate
rotation about the vertical is quiet too, but short or far from the bias). The rest level at any
time is interpolated linearly between the static intervals' mean rates (constant beyond the
first and last), so integrals of the rate and rate-table rates are taken against the bias of
their own time. Quiet intervals left out are listed with their mean rate in the notes.

**Motions** are the stretches between static intervals. The raw rate minus the rest level (of
its time) is integrated with the real timestamps (trapezoid); the dominant raw axis is the axis of largest
absolute angle (misalignment is unknown before calibration). A motion is a full-turn *phase*
when its raw turns ``r`` round to ``k >= 1`` with ``|r / k - 1| <= scale_tol`` (the gyro scale is
unknown to ~15 %), else a *transition*. A motion *clipped* at the gyroscope range (at least
:data:`MIN_CLIPPED_SAMPLES` samples and 2 % of its samples on the recording's extreme reading
of the dominant axis) reads fewer raw turns than it made: it is a phase when the protocol order
expects one about its axis there and ``r`` is at least half a turn; its ``turns`` is then NaN
(unknown), and the notes name it.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from scipy import special  # chi-square quantiles without scipy.stats' 0.5 s import per job

from imucal.columns import AXES
from imucal.ingest.timebase import nominal_period

#: Quantile of the window variances that seeds the noise estimate (see module docstring).
NOISE_QUANTILE = 0.1


#: Fewest samples on the extreme reading for a motion to count as clipped (an unclipped
#: recording holds its extreme in one or two samples).
MIN_CLIPPED_SAMPLES = 10


@dataclass(frozen=True)
class DetectorSettings:
    """Parameters of the quiet-window and static detectors.

    Attributes
    ----------
    window_s : float
        Moving-variance window, s.
    p_false : float
        Probability that a window of pure noise is called moving (per axis).
    min_static_s : float
        Shortest static interval (and shortest rate-table plateau), s.
    rest_tol_dps : float
        Largest difference between the mean raw rates of consecutive static intervals, deg/s.
    rest_drift_dps_per_s : float
        Largest drift of the rest level (the gyro bias) between static intervals, deg/s per s
        of time between them (a 15 K warm-up at 0.25 deg/s/K with a 200 s time constant starts
        at 0.019 deg/s/s).
    scale_tol : float
        Largest relative difference between a raw angle or rate and its nominal value
        (unknown gyro scale).
    """

    window_s: float = 0.5
    p_false: float = 1e-6
    min_static_s: float = 1.0
    rest_tol_dps: float = 2.0
    scale_tol: float = 0.2
    rest_drift_dps_per_s: float = 0.02

    def __post_init__(self) -> None:
        for name in (
            "window_s",
            "min_static_s",
            "rest_tol_dps",
            "scale_tol",
            "rest_drift_dps_per_s",
        ):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name} = {value!r}: expected a positive number")
        if not 0 < self.p_false < 0.5:
            raise ValueError(f"p_false = {self.p_false!r}: expected 0 < p_false < 0.5")


def moving_variance(x: np.ndarray, window: int) -> np.ndarray:
    """Variance (ddof 1) of every window of ``window`` consecutive samples.

    Parameters
    ----------
    x : ndarray, shape (n, k)
    window : int
        Samples per window, 2 <= window <= n.

    Returns
    -------
    ndarray, shape (n - window + 1, k)
        Row ``j`` is the variance of rows ``j .. j + window - 1``.
    """
    x = np.asarray(x, dtype=float)
    if not 2 <= window <= x.shape[0]:
        raise ValueError(f"window of {window} samples: expected 2 <= window <= {x.shape[0]} (n)")
    x = x - np.median(x, axis=0)  # centring keeps the running sums well conditioned
    zero = np.zeros((1, x.shape[1]))
    c1 = np.concatenate([zero, np.cumsum(x, axis=0)])
    c2 = np.concatenate([zero, np.cumsum(x * x, axis=0)])
    s1 = c1[window:] - c1[:-window]
    s2 = c2[window:] - c2[:-window]
    return np.maximum((s2 - s1 * s1 / window) / (window - 1), 0.0)


def _quantisation_step(x: np.ndarray) -> float:
    """Smallest difference between distinct values of ``x`` (n,); 0 if constant."""
    steps = np.diff(np.unique(x))
    steps = steps[steps > 0]
    return float(steps.min()) if steps.size else 0.0


def at_extreme(x: np.ndarray, a: int, b: int, sign: float, step: float | None = None) -> np.ndarray:
    """Rows ``a .. b - 1`` of one axis ``x`` (n,) that sit on the recording's extreme reading
    of the given sign (within half a quantisation ``step``, found from ``x`` when not given):
    readings clipped at the range."""
    extreme = x.max() if sign > 0 else x.min()
    step = _quantisation_step(x) if step is None else step
    return np.abs(x[a:b] - extreme) <= step / 2


def _clipped_windows(x: np.ndarray, window: int, steps: np.ndarray) -> np.ndarray:
    """Windows (n - window + 1, k) holding a reading clipped at the range on that axis: the
    axis's extreme reading of either sign, when at least :data:`MIN_CLIPPED_SAMPLES` hold it.
    ``steps`` (k,): the quantisation step of each axis."""
    out = np.zeros((x.shape[0] - window + 1, x.shape[1]), dtype=bool)
    for k in range(x.shape[1]):
        for sign in (1.0, -1.0):
            hit = at_extreme(x[:, k], 0, x.shape[0], sign, steps[k])
            if hit.sum() >= MIN_CLIPPED_SAMPLES:
                c = np.concatenate([[0], np.cumsum(hit)])
                out[:, k] |= (c[window:] - c[:-window]) > 0
    return out


def find_quiet_windows(x: np.ndarray, window: int, p_false: float) -> tuple[np.ndarray, np.ndarray]:
    """Windows whose variance is consistent with the sensor noise alone, on every axis.

    Parameters
    ----------
    x : ndarray, shape (n, k)
        One tri-axial signal (SI units).
    window : int
        Samples per window.
    p_false : float
        Per-axis probability that a pure-noise window exceeds the threshold.

    Returns
    -------
    quiet : ndarray of bool, shape (n - window + 1,)
        Window ``j`` (rows ``j .. j + window - 1``) is quiet.
    noise_var : ndarray, shape (k,)
        Estimated noise variance per axis (unit of ``x`` squared).

    Raises
    ------
    ValueError
        If the signal is constant on some axis (no noise and no quantisation step to use).
    """
    x = np.asarray(x, dtype=float)
    var = moving_variance(x, window)
    dof = window - 1
    steps = np.array([_quantisation_step(x[:, k]) for k in range(x.shape[1])])
    floor = steps**2 / 12
    # seed: the quietest NOISE_QUANTILE of the windows are noise only; windows that touch a
    # reading clipped at the sensor range hold less noise and are left out of that axis's seed
    clean = ~_clipped_windows(x, window, steps)
    seed = [
        np.quantile(v[ok], NOISE_QUANTILE) if ok.any() else np.quantile(v, NOISE_QUANTILE)
        for v, ok in zip(var.T, clean.T)
    ]
    noise = np.maximum(np.array(seed) / (special.chdtri(dof, 1 - NOISE_QUANTILE) / dof), floor)
    limit = special.chdtri(dof, p_false) / dof
    quiet = np.all(var <= limit * noise, axis=1)
    if quiet.any():  # refine on the windows found quiet
        noise = np.maximum(np.median(var[quiet], axis=0) / (special.chdtri(dof, 0.5) / dof), floor)
        quiet = np.all(var <= limit * noise, axis=1)
    if np.any(noise <= 0):
        raise ValueError(
            f"signal constant on axis {int(np.argmin(noise))} over all {x.shape[0]} samples: "
            "expected sensor noise or at least a quantisation step"
        )
    return quiet, noise


def windows_to_intervals(quiet: np.ndarray, window: int) -> list[tuple[int, int]]:
    """Sample intervals (end exclusive) covered by runs of quiet windows."""
    edges = np.diff(np.concatenate(([0], quiet.astype(np.int8), [0])))
    starts = np.flatnonzero(edges == 1)
    ends = np.flatnonzero(edges == -1)  # first non-quiet window after the run
    return [(int(a), int(b - 1 + window)) for a, b in zip(starts, ends)]


def window_samples(t_s: np.ndarray, window_s: float) -> int:
    return max(round(window_s / nominal_period(t_s)), 2)


def find_quiet_intervals(
    t_s: np.ndarray, x: np.ndarray, settings: DetectorSettings = DetectorSettings()
) -> list[tuple[int, int]]:
    """Intervals (row ranges, end exclusive) where ``x`` shows noise only, at least
    ``settings.min_static_s`` long. ``t_s`` shape (n,), ``x`` shape (n, k)."""
    window = window_samples(t_s, settings.window_s)
    quiet, _ = find_quiet_windows(x, window, settings.p_false)
    return [
        (a, b)
        for a, b in windows_to_intervals(quiet, window)
        if t_s[b - 1] - t_s[a] >= settings.min_static_s
    ]


#: Variance window of the search for rests shorter than ``min_static_s``, s: half the default
#: window, so that a 0.5 s stillness between a robot's moves still fills two windows.
SHORT_WINDOW_S = 0.25


def find_short_rests(
    t_s: np.ndarray, acc: np.ndarray, gyr: np.ndarray, settings: DetectorSettings
) -> list[tuple[float, float]]:
    """Still intervals (quiet gyroscope and accelerometer) too short for the static detector.

    The windows are :data:`SHORT_WINDOW_S` long (or ``settings.window_s`` if shorter); an
    interval counts when it spans at least two of them and less than ``settings.min_static_s``.
    Used to say which settings would find the rests of a recording that has none (a robot's
    rests between moves of about 1 s, shortened by the settling of the arm).

    Parameters
    ----------
    t_s : ndarray, shape (n,)
    acc, gyr : ndarray, shape (n, 3)
        Finite rows, SI units.
    settings : DetectorSettings

    Returns
    -------
    list of (float, float)
        Start and end of each interval, s.
    """
    t, acc, gyr = check_inputs(t_s, acc, gyr)
    window_s = min(SHORT_WINDOW_S, settings.window_s)
    window = window_samples(t, window_s)
    if t.size < 2 * window:
        return []
    quiet_g, _ = find_quiet_windows(gyr, window, settings.p_false)
    quiet_a, _ = find_quiet_windows(acc, window, settings.p_false)
    return [
        (float(t[a]), float(t[b - 1]))
        for a, b in windows_to_intervals(quiet_g & quiet_a, window)
        if 2 * window_s <= t[b - 1] - t[a] < settings.min_static_s
    ]


def check_inputs(t_s: np.ndarray, acc: np.ndarray, gyr: np.ndarray) -> tuple[np.ndarray, ...]:
    t = np.asarray(t_s, dtype=float)
    acc = np.asarray(acc, dtype=float)
    gyr = np.asarray(gyr, dtype=float)
    for name, x in (("acc", acc), ("gyr", gyr)):
        if x.shape != (t.size, 3):
            raise ValueError(f"{name} has shape {x.shape}; expected ({t.size}, 3) like t_s")
        bad = np.flatnonzero(~np.isfinite(x).all(axis=1))
        if bad.size:
            raise ValueError(
                f"{name}: {bad.size} row(s) with NaN/inf, first at row {bad[0]}; expected finite"
            )
    nominal_period(t)  # at least 2 samples, never decreasing, a positive median step
    return t, acc, gyr


@dataclass(frozen=True)
class StaticIntervals:
    """Static intervals of a recording and the raw gyro rest level over time.

    Attributes
    ----------
    intervals : list of (int, int)
        Row ranges, end exclusive, in time order.
    levels_rad_s : ndarray, shape (m, 3)
        Mean raw rate of each static interval (the gyro bias of its time), rad/s.
    centres_s : ndarray, shape (m,)
        Mid time of each static interval, s.
    rejected : list of (int, int, ndarray)
        Quiet intervals not at the rest level: row range and mean raw rate (3,), rad/s.
    """

    intervals: list
    levels_rad_s: np.ndarray
    centres_s: np.ndarray
    rejected: list = ()

    @property
    def rest_rad_s(self) -> np.ndarray:
        """Mean raw rate of all static samples, rad/s, shape (3,)."""
        n = np.array([b - a for a, b in self.intervals], dtype=float)
        return n @ self.levels_rad_s / n.sum()

    def rest_at(self, t_s: np.ndarray) -> np.ndarray:
        """Rest level at times ``t_s`` (n,): linear between the static intervals' means,
        constant beyond the first and the last; shape (n, 3), rad/s."""
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        return np.column_stack(
            [np.interp(t, self.centres_s, self.levels_rad_s[:, k]) for k in range(3)]
        )

    def drift_dps(self) -> float:
        """Largest change of the rest level between static intervals, deg/s."""
        spread = self.levels_rad_s.max(axis=0) - self.levels_rad_s.min(axis=0)
        return float(np.degrees(np.linalg.norm(spread)))


def rest_chain(
    centres_s: np.ndarray, means: np.ndarray, durations_s: np.ndarray, tol: float, drift: float
) -> np.ndarray:
    """The longest chain of intervals whose mean rates could all be the drifting gyro bias.

    Parameters
    ----------
    centres_s : ndarray, shape (m,)
        Mid times of the quiet intervals, increasing, s.
    means : ndarray, shape (m, 3)
        Their mean raw rates (any rate unit).
    durations_s : ndarray, shape (m,)
        Their durations, s.
    tol : float
        Largest difference between consecutive members (rate unit).
    drift : float
        Allowed further difference per second between them (rate unit per s).

    Returns
    -------
    ndarray of bool, shape (m,)
        Members of the chain of largest total duration (the earliest seed on a tie).
    """
    m = len(centres_s)
    best, best_len = np.zeros(m, bool), -1.0
    for seed in range(m):
        member = np.zeros(m, bool)
        member[seed] = True
        for order in (range(seed + 1, m), range(seed - 1, -1, -1)):
            last = seed
            for j in order:
                gap = abs(centres_s[j] - centres_s[last])
                if np.linalg.norm(means[j] - means[last]) <= tol + drift * gap:
                    member[j] = True
                    last = j
        length = float(durations_s[member].sum())
        if length > best_len:
            best, best_len = member, length
    return best


def find_static_intervals(
    t_s: np.ndarray,
    acc: np.ndarray,
    gyr: np.ndarray,
    settings: DetectorSettings = DetectorSettings(),
) -> StaticIntervals:
    """Static intervals: quiet gyro and accelerometer, raw rate at the (drifting) rest level.

    Parameters
    ----------
    t_s : ndarray, shape (n,)
        Timestamps, s.
    acc : ndarray, shape (n, 3)
        Specific force, m/s^2 (uncalibrated).
    gyr : ndarray, shape (n, 3)
        Raw rate, rad/s (uncalibrated).
    settings : DetectorSettings

    Returns
    -------
    StaticIntervals

    Raises
    ------
    ValueError
        If no static interval of at least ``min_static_s`` is found.
    """
    t, acc, gyr = check_inputs(t_s, acc, gyr)
    window = window_samples(t, settings.window_s)
    quiet_g, _ = find_quiet_windows(gyr, window, settings.p_false)
    quiet_a, _ = find_quiet_windows(acc, window, settings.p_false)
    candidates = [
        (a, b)
        for a, b in windows_to_intervals(quiet_g & quiet_a, window)
        if t[b - 1] - t[a] >= settings.min_static_s
    ]
    if not candidates:
        raise ValueError(
            f"no static interval of at least {settings.min_static_s} s in {t[-1] - t[0]:.1f} s "
            f"of data (window {settings.window_s} s): expected the sensor to rest at some time"
        )
    means = np.array([gyr[a:b].mean(axis=0) for a, b in candidates])
    centres = np.array([(t[a] + t[b - 1]) / 2 for a, b in candidates])
    durations = np.array([t[b - 1] - t[a] for a, b in candidates])
    rest = rest_chain(
        centres, means, durations,
        np.radians(settings.rest_tol_dps), np.radians(settings.rest_drift_dps_per_s),
    )  # fmt: skip
    rejected = [(a, b, m) for (a, b), m, r in zip(candidates, means, rest) if not r]
    return StaticIntervals(
        [c for c, r in zip(candidates, rest) if r], means[rest], centres[rest], rejected
    )


def rest_note(
    recording: str, t_s: np.ndarray, static: StaticIntervals, rejected: bool = False
) -> str:
    """What the rest-level search decided, in the data's terms ('' when nothing to say); with
    ``rejected``, also the quiet intervals left out (where the protocol has no constant-rate
    motion, so each is a slow motion worth naming)."""
    parts = []
    drift = static.drift_dps()
    if drift > 0.5:
        parts.append(
            f"rest level (gyro bias) moves by {drift:.2f} deg/s over "
            f"{static.centres_s[-1] - static.centres_s[0]:.0f} s; rates are taken against the "
            "rest level interpolated in time"
        )
    if rejected and len(static.rejected):
        listed = ", ".join(
            f"{t_s[a]:.1f}-{t_s[b - 1]:.1f} s ({np.degrees(np.linalg.norm(m - static.rest_at(t_s[a])[0])):.1f} deg/s off)"
            for a, b, m in static.rejected[:6]
        )
        more = f" and {len(static.rejected) - 6} more" if len(static.rejected) > 6 else ""
        parts.append(
            f"{len(static.rejected)} quiet interval(s) not at the rest level (slow motions): "
            f"{listed}{more}"
        )
    return f"{recording}: " + "; ".join(parts) if parts else ""


@dataclass(frozen=True)
class Motion:
    """A stretch between static intervals and its raw rotation.

    Attributes
    ----------
    start, end : int
        Row range, end exclusive.
    angle_rad : ndarray, shape (3,)
        Integral of (raw rate - rest level) over the motion, rad, per raw axis.
    """

    start: int
    end: int
    angle_rad: np.ndarray

    @property
    def axis(self) -> str:
        return AXES[int(np.argmax(np.abs(self.angle_rad)))]

    @property
    def raw_turns(self) -> float:
        """Signed raw turns about the dominant axis."""
        return float(self.angle_rad[AXES.index(self.axis)] / (2 * np.pi))


def integrate_rate(t_s: np.ndarray, rate: np.ndarray, start: int, end: int) -> np.ndarray:
    """Trapezoid integral of ``rate`` (n, 3) over rows ``start .. end - 1`` with the real
    timestamps ``t_s`` (n,); returns shape (3,), rate unit times s."""
    if end - start < 2:
        return np.zeros(rate.shape[1])
    return np.trapezoid(rate[start:end], t_s[start:end], axis=0)


def find_motions(t_s: np.ndarray, gyr: np.ndarray, static: StaticIntervals) -> list[Motion]:
    """The stretches before, between and after static intervals with their raw angles.

    Each motion runs from the last row of the static interval before it to the first row of the
    one after it, so that the integral covers the whole rotation.
    """
    t = np.asarray(t_s, dtype=float)
    rate = np.asarray(gyr, dtype=float) - static.rest_at(t)
    bounds = [(0, 0), *static.intervals, (t.size, t.size)]
    motions = []
    for (_, prev_end), (next_start, _) in itertools.pairwise(bounds):
        if next_start - prev_end <= 0:
            continue
        a, b = max(prev_end - 1, 0), min(next_start + 1, t.size)
        motions.append(Motion(prev_end, next_start, integrate_rate(t, rate, a, b)))
    return motions


def is_clipped(x: np.ndarray, a: int, b: int) -> bool:
    """Rows ``a .. b - 1`` of a recording's signal ``x`` (n, k) sit on an extreme reading of
    the recording (either sign, any axis) long enough to be clipped at the range: at least
    :data:`MIN_CLIPPED_SAMPLES` samples and 2 % of the rows."""
    enough = max(MIN_CLIPPED_SAMPLES, 0.02 * (b - a))
    return any(
        at_extreme(x[:, k], a, b, sign).sum() >= enough
        for k in range(x.shape[1])
        for sign in (1.0, -1.0)
    )
