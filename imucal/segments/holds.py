"""Static holds of a hand-held pose session: a threshold that adapts to the tremor.

The noise-derived detector (:mod:`imucal.segments.detector`) calls a window quiet when its variance is
what white sensor noise alone would give. A pose held by hand for a few seconds is not quiet in
that sense: the hand's tremor (about 0.5 deg at 4-12 Hz) adds variance, and such a hold is
rejected. The cube fit (eq. 32) does not need a noise-only hold, only the mean specific force of
a hold, and tremor about a fixed pose averages out of the mean.

**Method** (Tedaldi, Pretto, Menegatti 2014, the static detector of imu_tk). The statistic of
a window of ``window_s`` is the total variance of the accelerometer, the sum of the per-axis
variances (m^2/s^4). The *base* is the median statistic of the windows of an initial static
interval ``T_init`` (the longest static interval the noise-derived detector finds; in the
method the module rests on a table for ``T_init`` before the poses). Without one, the base is
the ``NOISE_QUANTILE`` quantile of all windows (the quietest windows, as in the noise seed of
:func:`imucal.segments.detector.find_quiet_windows`). For each multiple ``k`` of
``HOLD_MULTIPLES`` a window is still when its statistic is at most ``k`` times the base, and a
hold is a run of still windows of at least ``min_static_s`` (the samples they cover; runs whose
samples overlap, split by fewer loud windows than a window's length, are one hold, and so are
consecutive holds whose means point within ``SAME_HOLD_DEG`` of each other: a tremor burst that
splits a pose must not count as a second pose). The cube
fit (:func:`imucal.fits.accelerometer.fit_cube`, eq. 32) is run on the holds of every multiple that
gives at least ``MIN_HOLDS``; its residual is the standard error of ``|S'(mean - o)| - g`` over
the hold means, ``sqrt(sum r^2 / (n - 9))`` (the in-sample RMS would reward the fewest holds:
nine holds fit exactly). A small multiple misses the shakier holds; a large one lets the ends
of the motions into the holds, which pulls their means off the ellipsoid and raises the
residual. The multiple chosen has the smallest residual; a residual whose square is not
significantly larger (F test at ``TIE_ALPHA``, ``n - 9`` degrees of freedom each: with 10 holds
one residual says little) ties with it, and ties go to the multiple with more holds (more
equations for the same fit quality), then to the smaller residual.

**Accelerometer only.** As in imu_tk, the gyroscope takes no part. Tremor is a small rotation
``theta(t)``: the accelerometer sees it as ``g theta`` (about 0.09 m/s^2 for 0.5 deg), the
gyroscope as its rate ``2 pi f theta`` (about 20 deg/s at 7 Hz), so the gyro variance of a
hand-held pose exceeds the rest level by orders of magnitude more than the accelerometer's, and
no multiple of a common base separates holds from motions in both sensors. What the cube fit
needs, a hold whose mean is a fixed orientation, is what the accelerometer shows: a slow turn
during a hold moves the specific force and raises the accelerometer variance too.

**First choice.** The noise-derived detector stays the first choice (its holds are rest, not
held). :func:`imucal.segments.protocol.segment_poses` calls :func:`find_holds` only when it finds
fewer than ``MIN_HOLDS`` holds, and keeps its own holds when no multiple gives enough.

The residual uses standard gravity: the hold means do not depend on it, and the local value
only scales ``S'``.

References
----------
Tedaldi, Pretto, Menegatti, "A robust and easy to implement method for IMU calibration without
external equipments", ICRA 2014, sec. IV-A (static detector, threshold multiples of the
initial variance chosen by the accelerometer residual).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import special  # F quantiles without scipy.stats' 0.5 s import per job

from imucal.constants import STANDARD_GRAVITY_M_S2
from imucal.fits.accelerometer import MIN_POSITIONS, fit_cube
from imucal.segments.detector import (
    NOISE_QUANTILE,
    DetectorSettings,
    moving_variance,
    window_samples,
    windows_to_intervals,
)

#: Multiples of the base variance tried (imu_tk: 2 to 10; larger ones for strong tremor).
HOLD_MULTIPLES = (2, 3, 4, 5, 6, 7, 8, 9, 10, 15, 20, 30, 50)
#: Holds the cube fit needs (9 parameters, one equation per hold).
MIN_HOLDS = MIN_POSITIONS
#: Consecutive holds closer in direction than this are one pose split by a tremor burst, deg
#: (tremor of 0.5 deg moves a hold's mean far less; ck_explorer's staircase steps are >= 1.5 deg).
SAME_HOLD_DEG = 1.0
#: Level of the F test below which a larger residual still ties with the smallest.
TIE_ALPHA = 0.05


@dataclass(frozen=True)
class HoldTrial:
    """The holds found at one multiple of the base variance and the cube fit on them.

    Attributes
    ----------
    multiple : float
        Threshold / base variance.
    n_holds : int
    residual_m_s2 : float
        Standard error of ``|S'(mean - o)| - g`` over the hold means, m/s^2; NaN when there are
        fewer than ``MIN_HOLDS + 1`` holds or the fit failed.
    """

    multiple: float
    n_holds: int
    residual_m_s2: float


@dataclass(frozen=True)
class AdaptiveHolds:
    """Result of :func:`find_holds`.

    Attributes
    ----------
    intervals : list of (int, int)
        Row ranges (end exclusive) of the holds at the chosen multiple, in time order; empty
        when no multiple gives ``MIN_HOLDS``.
    multiple : float or None
        Chosen multiple; None when no multiple gives ``MIN_HOLDS`` holds.
    base_var_m2_s4 : float
        Base window variance (sum over axes), m^2/s^4.
    base : str
        Where the base came from.
    trials : tuple of HoldTrial
        One per multiple tried, in ``HOLD_MULTIPLES`` order.
    """

    intervals: list
    multiple: float | None
    base_var_m2_s4: float
    base: str
    trials: tuple

    def describe(self) -> str:
        """One line for the segments table's notes: detector, multiple, why, residuals."""
        per = ", ".join(
            f"{tr.multiple:g}x: {tr.n_holds}"
            + (f" ({tr.residual_m_s2:.4f} m/s^2)" if np.isfinite(tr.residual_m_s2) else "")
            for tr in self.trials
        )
        residuals = [tr.residual_m_s2 for tr in self.trials if np.isfinite(tr.residual_m_s2)]
        chosen = next((tr for tr in self.trials if tr.multiple == self.multiple), None)
        why = (
            "exactly determined, no residual"
            if chosen is None or not np.isfinite(chosen.residual_m_s2)
            else "the smallest cube-fit residual"
            if chosen.residual_m_s2 == min(residuals)
            else "the most holds among residuals not significantly above the smallest (F test)"
        )
        head = (
            f"threshold {self.multiple:g} x the base variance {self.base_var_m2_s4:.3g} m^2/s^4 "
            f"({self.base}): {len(self.intervals)} holds, {why}"
            if self.multiple is not None
            else f"no multiple of the base variance {self.base_var_m2_s4:.3g} m^2/s^4 "
            f"({self.base}) gave {MIN_HOLDS} holds"
        )
        return f"{head}; holds (cube-fit residual) per multiple: {per}"


def hold_variance(acc: np.ndarray, window: int) -> np.ndarray:
    """Total variance (sum over axes, ddof 1) of every window of ``window`` samples.

    Parameters
    ----------
    acc : ndarray, shape (n, 3)
        Specific force, m/s^2.
    window : int
        Samples per window.

    Returns
    -------
    ndarray, shape (n - window + 1,)
        m^2/s^4; entry ``j`` covers rows ``j .. j + window - 1``.
    """
    return moving_variance(acc, window).sum(axis=1)


def merge_overlapping(intervals: list[tuple[int, int]]) -> list[tuple[int, int]]:
    """Row intervals (end exclusive) that share a row merged into one, in time order.

    Two runs of still windows of one rest, split by a few louder windows (a twitch, a tremor
    burst) shorter than a window, cover overlapping rows: they are one hold. Runs that only
    touch (no shared row) are two holds: a one-sample step between two orientations leaves
    exactly that (a logger that jumps from one block of a pose to the next).
    """
    merged: list[list[int]] = []
    for a, b in sorted(intervals):
        if merged and a < merged[-1][1]:
            merged[-1][1] = max(merged[-1][1], b)
        else:
            merged.append([a, b])
    return [(a, b) for a, b in merged]


def merge_same_direction(
    intervals: list[tuple[int, int]], acc: np.ndarray, max_deg: float
) -> list[tuple[int, int]]:
    """Consecutive holds whose mean specific force points the same way (within ``max_deg``,
    deg) merged into one hold from the first start to the last end; ``acc`` (n, 3) m/s^2."""
    merged: list[list[int]] = []
    last = None
    for a, b in intervals:
        u = acc[a:b].mean(axis=0)
        u = u / np.linalg.norm(u)
        if last is not None and np.degrees(np.arccos(min(float(u @ last), 1.0))) < max_deg:
            merged[-1][1] = b
        else:
            merged.append([a, b])
            last = u
    return [(a, b) for a, b in merged]


def _residual(intervals: list[tuple[int, int]], acc: np.ndarray, gravity_m_s2: float) -> float:
    """Standard error of the cube fit on the holds' means (NaN if undetermined or failed)."""
    if len(intervals) <= MIN_HOLDS:
        return np.nan
    try:
        fit = fit_cube([acc[a:b] for a, b in intervals], gravity_m_s2)
    except ValueError:  # degenerate directions or too few usable holds: no residual
        return np.nan
    r = fit.magnitude_error_after_m_s2
    return float(np.sqrt(np.sum(r**2) / (r.size - MIN_HOLDS)))


def _choose(trials: list[HoldTrial]) -> HoldTrial | None:
    """Smallest residual; residuals not significantly larger (F test) are ties, to more holds."""
    fitted = [tr for tr in trials if np.isfinite(tr.residual_m_s2)]
    if not fitted:  # at best exactly determined: the strictest multiple that gives enough
        return next((tr for tr in trials if tr.n_holds >= MIN_HOLDS), None)
    best = min(fitted, key=lambda tr: tr.residual_m_s2)

    def tie(tr: HoldTrial) -> bool:
        ratio = (tr.residual_m_s2 / best.residual_m_s2) ** 2
        dof = tr.n_holds - MIN_HOLDS, best.n_holds - MIN_HOLDS
        return ratio <= special.fdtri(*dof, 1 - TIE_ALPHA)

    return max(filter(tie, fitted), key=lambda tr: (tr.n_holds, -tr.residual_m_s2))


def find_holds(
    t_s: np.ndarray,
    acc: np.ndarray,
    settings: DetectorSettings,
    *,
    base_interval: tuple[int, int] | None = None,
    multiples: tuple[float, ...] = HOLD_MULTIPLES,
) -> AdaptiveHolds:
    """Hand-held holds: accelerometer windows within a multiple of the base variance.

    Parameters
    ----------
    t_s : ndarray, shape (n,)
        Timestamps, s (never decreasing).
    acc : ndarray, shape (n, 3)
        Specific force, m/s^2 (uncalibrated), finite.
    settings : DetectorSettings
        ``window_s`` (variance window, s) and ``min_static_s`` (shortest hold, s) are used.
    base_interval : (int, int), optional
        Rows (end exclusive) of the initial static interval ``T_init``; without it the quietest
        ``NOISE_QUANTILE`` of the windows set the base.
    multiples : tuple of float
        Threshold multiples of the base to try, each > 0.

    Returns
    -------
    AdaptiveHolds

    Raises
    ------
    ValueError
        If ``acc`` is not (n, 3) like ``t_s``, ``base_interval`` holds fewer rows than a window
        or lies outside the data, or a multiple is not positive.
    """
    t = np.asarray(t_s, dtype=float)
    acc = np.asarray(acc, dtype=float)
    if acc.shape != (t.size, 3):
        raise ValueError(f"acc has shape {acc.shape}; expected ({t.size}, 3) like t_s")
    if not all(np.isfinite(k) and k > 0 for k in multiples):
        raise ValueError(f"multiples {multiples}: expected positive numbers")
    window = window_samples(t, settings.window_s)
    stat = hold_variance(acc, window)
    if base_interval is None:
        base = float(np.quantile(stat, NOISE_QUANTILE))
        source = f"the quietest {NOISE_QUANTILE:.0%} of the {settings.window_s:g} s windows"
    else:
        a, b = base_interval
        if not (0 <= a and b <= t.size and b - a >= window):
            raise ValueError(
                f"base_interval rows {a}-{b}: expected at least one window ({window} samples) "
                f"inside the {t.size} rows"
            )
        base = float(np.median(stat[a : b - window + 1]))
        source = f"static interval {t[a]:.1f}-{t[b - 1]:.1f} s"
    trials, found = [], {}
    for k in multiples:
        intervals = [
            (a, b)
            for a, b in merge_overlapping(windows_to_intervals(stat <= k * base, window))
            if t[b - 1] - t[a] >= settings.min_static_s
        ]
        intervals = merge_same_direction(intervals, acc, SAME_HOLD_DEG)
        found[k] = intervals
        trials.append(
            HoldTrial(float(k), len(intervals), _residual(intervals, acc, STANDARD_GRAVITY_M_S2))
        )
    chosen = _choose(trials)
    return AdaptiveHolds(
        intervals=found[chosen.multiple] if chosen else [],
        multiple=chosen.multiple if chosen else None,
        base_var_m2_s4=base,
        base=source,
        trials=tuple(trials),
    )
