"""Automatic segmentation of the protocol recordings: static intervals, rotation3d phases, cube
positions and rate-table runs, with the manual override of ``dataset.yaml``.

The paper (Zhang et al. 2014) segments by hand; the rules here are the implementer's.

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

**Cube positions** are static intervals; consecutive ones whose mean specific force points the
same way (within half the 45-degree V-block step, 22.5 deg) are one position (a yaw about the
vertical does not give the cube fit a new point): the longest is kept, the others are labelled
``static``. A cube turned by hand rests with tremor above the noise: when the static intervals
give fewer positions than the fit needs, the holds of the tremor-adaptive detector
(:func:`imucal.segments.holds.find_holds`) are grouped the same way, and the notes say so.

**Rate-table runs** are gyro-quiet intervals (constant rate, not necessarily zero) of at least
``min_static_s`` (the steady part: the ends of the spin-up and spin-down stay within the noise
there) whose rate differs from the rest level by at least half the smallest non-zero
table rate; they are matched in time order to ``axes`` x ``rates_dps``. Nothing depends on the
plateau length beyond ``min_static_s``. Two such intervals about the same raw axis and sense with
no static interval between them (the table did not stop) and mean rates closer than half the
smallest step between nominal rates, scaled by ``1 - scale_tol``, are one run split by a
disturbance (a vibration, a lost packet burst): the longest piece is kept. A run is *clipped*
when at least half of its samples on the dominant axis sit on the recording's extreme reading
of that sign (the ADC's range): unclipped, the samples of a plateau spread over the noise, and no
single quantisation level holds more than ``step / (sigma sqrt(2 pi))`` of them (< 1/2 once the
noise ``sigma`` exceeds 0.8 quantisation steps). A clipped reading is only a lower bound on the
raw rate, so a clipped run matches its nominal rate when the axis and sense agree and the reading
is not above the nominal rate times ``1 + scale_tol``; its quiet interval also holds the clipped
ends of the ramps, so it is cut to the median length of the unclipped runs of its axis around its
centre, and the clipped runs are listed in ``attrs['notes']`` (the fits leave them out by the
sensor range). A 0 deg/s run is the static interval between its neighbouring runs, cut the same
way.
"""

from __future__ import annotations

import itertools
import logging
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import stats

from imucal.columns import ACC, AXES, GYR, KINDS, SEGMENT_COLUMNS, TIME
from imucal.constants import IMU_RECORDINGS, OTHER_RECORDINGS
from imucal.segments.filtering import nominal_period

logger = logging.getLogger(__name__)


#: Half the 45-deg step between cube positions: gravity directions closer than this are one.
SAME_POSITION_DEG = 22.5
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
    noise = np.maximum(np.array(seed) / (stats.chi2.ppf(NOISE_QUANTILE, dof) / dof), floor)
    limit = stats.chi2.ppf(1 - p_false, dof) / dof
    quiet = np.all(var <= limit * noise, axis=1)
    if quiet.any():  # refine on the windows found quiet
        noise = np.maximum(np.median(var[quiet], axis=0) / (stats.chi2.median(dof) / dof), floor)
        quiet = np.all(var <= limit * noise, axis=1)
    if np.any(noise <= 0):
        raise ValueError(
            f"signal constant on axis {int(np.argmin(noise))} over all {x.shape[0]} samples: "
            "expected sensor noise or at least a quantisation step"
        )
    return quiet, noise


def _windows_to_intervals(quiet: np.ndarray, window: int) -> list[tuple[int, int]]:
    """Sample intervals (end exclusive) covered by runs of quiet windows."""
    edges = np.diff(np.concatenate(([0], quiet.astype(np.int8), [0])))
    starts = np.flatnonzero(edges == 1)
    ends = np.flatnonzero(edges == -1)  # first non-quiet window after the run
    return [(int(a), int(b - 1 + window)) for a, b in zip(starts, ends)]


def _window_samples(t_s: np.ndarray, window_s: float) -> int:
    return max(round(window_s / nominal_period(t_s)), 2)


def find_quiet_intervals(
    t_s: np.ndarray, x: np.ndarray, settings: DetectorSettings = DetectorSettings()
) -> list[tuple[int, int]]:
    """Intervals (row ranges, end exclusive) where ``x`` shows noise only, at least
    ``settings.min_static_s`` long. ``t_s`` shape (n,), ``x`` shape (n, k)."""
    window = _window_samples(t_s, settings.window_s)
    quiet, _ = find_quiet_windows(x, window, settings.p_false)
    return [
        (a, b)
        for a, b in _windows_to_intervals(quiet, window)
        if t_s[b - 1] - t_s[a] >= settings.min_static_s
    ]


def _check_inputs(t_s: np.ndarray, acc: np.ndarray, gyr: np.ndarray) -> tuple[np.ndarray, ...]:
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
    t, acc, gyr = _check_inputs(t_s, acc, gyr)
    window = _window_samples(t, settings.window_s)
    quiet_g, _ = find_quiet_windows(gyr, window, settings.p_false)
    quiet_a, _ = find_quiet_windows(acc, window, settings.p_false)
    candidates = [
        (a, b)
        for a, b in _windows_to_intervals(quiet_g & quiet_a, window)
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


def _describe(t: np.ndarray, m: Motion) -> str:
    return (
        f"about {m.axis} {np.degrees(m.angle_rad[AXES.index(m.axis)]):+.0f} deg raw "
        f"({m.raw_turns:+.2f} turns) at {t[m.start]:.1f}-{t[m.end - 1]:.1f} s"
    )


def _row(recording, label, kind, t, a, b, axis="", rate_dps=np.nan, sense=0, turns=np.nan,
         up="", angle_deg=np.nan):  # fmt: skip
    return {
        "recording": recording, "label": label, "kind": kind,
        "start_s": float(t[a]), "end_s": float(t[b - 1]), "start_index": int(a), "end_index": int(b),
        "axis": axis, "rate_dps": float(rate_dps), "sense": int(sense), "turns": float(turns),
        "up": up, "angle_deg": float(angle_deg),
    }  # fmt: skip


def _frame(rows: list[dict]) -> pd.DataFrame:
    frame = pd.DataFrame(rows, columns=list(SEGMENT_COLUMNS))
    return frame.astype(
        {
            "start_s": float,
            "end_s": float,
            "start_index": np.int64,
            "end_index": np.int64,
            "rate_dps": float,
            "sense": np.int64,
            "turns": float,
            "angle_deg": float,
        }
    )


def _full_turns(raw_turns: float, scale_tol: float) -> int:
    """Nearest whole number of turns when the raw value is one within the scale tolerance."""
    k = round(abs(raw_turns))
    if k >= 1 and abs(abs(raw_turns) / k - 1) <= scale_tol:
        return k
    return 0


def segment_rotation3d(
    t_s: np.ndarray,
    acc: np.ndarray,
    gyr: np.ndarray,
    settings: DetectorSettings = DetectorSettings(),
) -> pd.DataFrame:
    """Static intervals, phases x, y, z and transitions of the 3-D platform recording.

    Parameters
    ----------
    t_s : ndarray, shape (n,)
        Timestamps, s.
    acc, gyr : ndarray, shape (n, 3)
        Uncalibrated specific force (m/s^2) and rate (rad/s).
    settings : DetectorSettings

    Returns
    -------
    DataFrame
        Segments table rows (docs/architecture.md): ``s01``.. static, ``x``, ``y``, ``z`` phases
        with ``sense`` and whole signed ``turns``, ``t01``.. transitions with raw signed turns.

    Raises
    ------
    ValueError
        If the phases (full-turn or clipped motions) are not exactly one about x, then y,
        then z; the message lists every motion found (raw axis, angle, time).
    """
    t, acc, gyr = _check_inputs(t_s, acc, gyr)
    static = find_static_intervals(t, acc, gyr, settings)
    motions = find_motions(t, gyr, static)
    clipped = [m for m in motions if abs(m.raw_turns) >= 0.5 and is_clipped(gyr, m.start, m.end)]
    phases = [m for m in motions if _full_turns(m.raw_turns, settings.scale_tol) or m in clipped]
    if [m.axis for m in phases] != list(AXES):
        found = "; ".join(_describe(t, m) for m in motions) or "none"
        raise ValueError(
            f"rotation3d: expected one full-turn phase about x, then y, then z (raw turns within "
            f"{settings.scale_tol:.0%} of a whole number); found full-turn phases about "
            f"{[m.axis for m in phases]}; motions found: {found}"
        )
    rows = [
        _row("rotation3d", f"s{i:02d}", "static", t, a, b)
        for i, (a, b) in enumerate(static.intervals, start=1)
    ]
    n_transition = 0
    for m in motions:
        if m in phases:
            k = np.nan if m in clipped else _full_turns(m.raw_turns, settings.scale_tol)
            sense = int(np.sign(m.raw_turns))
            rows.append(
                _row(
                    "rotation3d",
                    m.axis,
                    "phase",
                    t,
                    m.start,
                    m.end,
                    m.axis,
                    np.nan,
                    sense,
                    sense * k,
                )
            )
            logger.info("rotation3d: phase %s", _describe(t, m))
        else:
            n_transition += 1
            rows.append(
                _row(
                    "rotation3d",
                    f"t{n_transition:02d}",
                    "transition",
                    t,
                    m.start,
                    m.end,
                    m.axis,
                    np.nan,
                    int(np.sign(m.raw_turns)),
                    m.raw_turns,
                )
            )
    out = _frame(rows).sort_values("start_s", kind="stable").reset_index(drop=True)
    notes = [rest_note("rotation3d", t, static).removeprefix("rotation3d: ")]
    if clipped:
        notes.append(
            "phase(s) "
            + ", ".join(f"{m.axis} ({m.raw_turns:+.2f} raw turns)" for m in clipped)
            + " clipped at the gyroscope range: a phase by the protocol order, its number of "
            "turns unknown (the raw angle is a lower bound)"
        )
        logger.warning("rotation3d: %s", notes[-1])
    notes = [n for n in notes if n]
    out.attrs["notes"] = {"rotation3d": "rotation3d: " + "; ".join(notes)} if notes else {}
    return out


def segment_cube(
    t_s: np.ndarray,
    acc: np.ndarray,
    gyr: np.ndarray,
    settings: DetectorSettings = DetectorSettings(),
    min_positions: int = 9,
) -> pd.DataFrame:
    """Static positions ``p01``.. of the cube recording, in time order.

    Parameters
    ----------
    t_s : ndarray, shape (n,)
    acc, gyr : ndarray, shape (n, 3)
        Uncalibrated specific force (m/s^2) and rate (rad/s).
    settings : DetectorSettings
    min_positions : int
        Fewest positions the cube fit (eq. 32: 9 parameters) accepts.

    Returns
    -------
    DataFrame
        Segments table rows: positions, and ``s01``.. for static intervals that repeat the
        gravity direction of the position next to them.

    Raises
    ------
    ValueError
        If fewer than ``min_positions`` distinct positions are found.
    """
    from imucal.segments.holds import find_holds  # holds builds on this module

    t, acc, gyr = _check_inputs(t_s, acc, gyr)
    try:
        static = find_static_intervals(t, acc, gyr, settings)
        intervals, rest = static.intervals, rest_note("cube", t, static, rejected=True)
    except ValueError as err:  # nothing at rest within the noise: maybe held by hand
        intervals, rest = [], f"cube: {err}"
    groups = _positions(acc, intervals)
    notes = [rest.removeprefix("cube: ")] if rest else []
    by_hand = False
    if len(groups) < min_positions:
        # poses held by hand: the tremor is above the noise (imucal.segments.holds)
        base = max(intervals, key=lambda ab: ab[1] - ab[0]) if intervals else None
        adaptive = find_holds(t, acc, settings, base_interval=base)
        held = _positions(acc, adaptive.intervals) if adaptive.multiple is not None else []
        notes.append(
            f"the noise-derived detector found {len(groups)} position(s); "
            + (f"holds from the tremor-adaptive detector (Tedaldi 2014), {adaptive.describe()}"
               if len(held) > len(groups) else f"tremor-adaptive detector: {adaptive.describe()}")
        )  # fmt: skip
        if len(held) > len(groups):
            groups, by_hand = held, True
    if len(groups) < min_positions:
        where = ", ".join(f"{t[g[0][0]]:.1f}-{t[g[-1][1] - 1]:.1f} s" for g in groups) or "none"
        raise ValueError(
            f"cube: found {len(groups)} static position(s) ({where}); the cube fit needs at least "
            f"{min_positions} (the protocol has 12); " + "; ".join(notes)
        )
    if len(groups) != 12:
        logger.warning("cube: found %d positions; the protocol has 12", len(groups))
    rows = []
    n_static = 0
    for i, group in enumerate(groups, start=1):
        keep = max(group, key=lambda ab: ab[1] - ab[0])
        for a, b in group:
            if (a, b) == keep:
                rows.append(_row("cube", f"p{i:02d}", "position", t, a, b))
            else:
                n_static += 1
                rows.append(_row("cube", f"s{n_static:02d}", "static", t, a, b))
    out = _frame(rows).sort_values("start_s", kind="stable").reset_index(drop=True)
    out.attrs["notes"] = {"cube": "cube: " + "; ".join(notes)} if notes else {}
    out.attrs["held_by_hand"] = ["cube"] if by_hand else []
    return out


def _positions(acc: np.ndarray, intervals: list[tuple[int, int]]) -> list[list[tuple[int, int]]]:
    """Consecutive static intervals grouped into positions: a group's mean specific forces
    (acc (n, 3)) point within ``SAME_POSITION_DEG`` of the one before."""
    groups: list[list[tuple[int, int]]] = []
    last_dir = None
    for a, b in intervals:
        g = acc[a:b].mean(axis=0)
        g = g / np.linalg.norm(g)
        if (
            last_dir is not None
            and np.degrees(np.arccos(np.clip(g @ last_dir, -1, 1))) < SAME_POSITION_DEG
        ):
            groups[-1].append((a, b))
        else:
            groups.append([(a, b)])
        last_dir = g
    return groups


@dataclass(frozen=True)
class ConstantRateRun:
    """A constant-rate stretch of the rate-table recording, before matching to the table.

    Attributes
    ----------
    start, end : int
        Row range, end exclusive.
    axis : str
        Dominant raw axis ('x', 'y' or 'z').
    rate_dps : float
        Mean raw rate minus the rest level about ``axis``, deg/s (signed).
    clipped : bool
        At least half of the samples on ``axis`` sit on the recording's extreme reading of that
        sign: the rate is at or beyond the sensor range, and ``rate_dps`` is only a lower bound.
    pieces : int
        Quiet intervals merged into this run (1 unless a disturbance split the plateau).
    """

    start: int
    end: int
    axis: str
    rate_dps: float
    clipped: bool
    pieces: int = 1


def find_constant_rate_runs(
    t_s: np.ndarray,
    gyr: np.ndarray,
    static: StaticIntervals,
    rates_dps: list[float],
    settings: DetectorSettings = DetectorSettings(),
) -> list[ConstantRateRun]:
    """Constant-rate runs of a rate-table recording, split plateaus merged, clipping flagged.

    Parameters
    ----------
    t_s : ndarray, shape (n,)
        Timestamps, s.
    gyr : ndarray, shape (n, 3)
        Raw rate, rad/s (uncalibrated).
    static : StaticIntervals
        Static intervals and rest level of the same recording.
    rates_dps : list of float
        Nominal table rates, deg/s; at least one non-zero.
    settings : DetectorSettings

    Returns
    -------
    list of ConstantRateRun
        In time order; see the module docstring for the rules.
    """
    t = np.asarray(t_s, dtype=float)
    gyr = np.asarray(gyr, dtype=float)
    nonzero = [abs(r) for r in rates_dps if r != 0]
    if not nonzero:
        raise ValueError(f"rates_dps {list(rates_dps)}: expected at least one non-zero rate")
    min_rate = np.radians(min(nonzero)) / 2
    levels = np.unique(np.concatenate([[0.0], np.asarray(rates_dps, dtype=float)]))
    # pieces of one run read the same rate; different runs differ by a nominal step times the
    # scale, at least (1 - scale_tol) of it
    same_rate_dps = (1 - settings.scale_tol) * float(np.diff(levels).min()) / 2
    pieces: list[ConstantRateRun] = []
    for a, b in find_quiet_intervals(t, gyr, settings):
        w = gyr[a:b].mean(axis=0) - static.rest_at((t[a] + t[b - 1]) / 2)[0]
        if np.linalg.norm(w) < min_rate:
            continue
        k = int(np.argmax(np.abs(w)))
        clipped = at_extreme(gyr[:, k], a, b, w[k]).mean() >= 0.5
        pieces.append(ConstantRateRun(a, b, AXES[k], float(np.degrees(w[k])), bool(clipped)))
    runs: list[ConstantRateRun] = []
    for p in pieces:
        prev = runs[-1] if runs else None
        if (
            prev is not None
            and prev.axis == p.axis
            and np.sign(prev.rate_dps) == np.sign(p.rate_dps)
            and abs(prev.rate_dps - p.rate_dps) < same_rate_dps
            and not any(a < p.start and b > prev.end for a, b in static.intervals)
        ):
            longer = max(prev, p, key=lambda r: r.end - r.start)
            runs[-1] = ConstantRateRun(
                longer.start, longer.end, longer.axis, longer.rate_dps,
                prev.clipped or p.clipped, prev.pieces + p.pieces,
            )  # fmt: skip
            logger.info(
                "ratetable: constant-rate run about %s split at %.2f-%.2f s; longest piece kept",
                p.axis, t[prev.end - 1], t[p.start],
            )  # fmt: skip
        else:
            runs.append(p)
    return runs


def segment_ratetable(
    t_s: np.ndarray,
    acc: np.ndarray,
    gyr: np.ndarray,
    axes: list[str],
    rates_dps: list[float],
    settings: DetectorSettings = DetectorSettings(),
) -> pd.DataFrame:
    """Constant-rate runs of the rate-table recording, matched to ``axes`` x ``rates_dps``.

    Parameters
    ----------
    t_s : ndarray, shape (n,)
    acc, gyr : ndarray, shape (n, 3)
        Uncalibrated specific force (m/s^2) and rate (rad/s).
    axes : list of str
        Table axes in recording order ('x', 'y', 'z' of frame B).
    rates_dps : list of float
        Table rates of each axis in recording order, deg/s (0 allowed).
    settings : DetectorSettings

    Returns
    -------
    DataFrame
        One row per run, label ``f"{axis}{rate:+d}"``, the steady part only; ``turns`` is the raw
        signed angle over it (NaN for 0 deg/s). ``attrs['notes']`` maps ``'ratetable'`` to a
        message naming the runs clipped at the sensor range and the runs a disturbance split
        (absent when there are none).

    Raises
    ------
    ValueError
        If the number of non-zero runs differs from the table's, a run's raw axis, sense or rate
        does not match (a clipped run's rate only from above), or a 0 deg/s run has no static
        interval between its neighbours.
    """
    t, acc, gyr = _check_inputs(t_s, acc, gyr)
    static = find_static_intervals(t, acc, gyr, settings)
    found = find_constant_rate_runs(t, gyr, static, rates_dps, settings)
    min_rate_dps = min(abs(r) for r in rates_dps if r != 0) / 2
    expected = [(ax, r) for ax in axes for r in rates_dps]
    expected_nonzero = [(ax, r) for ax, r in expected if r != 0]

    def listing() -> str:
        return (
            "; ".join(
                f"about {run.axis} {run.rate_dps:+.0f} deg/s raw"
                f"{' (clipped)' if run.clipped else ''} at {t[run.start]:.1f}-{t[run.end - 1]:.1f} s"
                for run in found
            )
            or "none"
        )

    if len(found) != len(expected_nonzero):
        raise ValueError(
            f"ratetable: found {len(found)} constant-rate run(s) of at least "
            f"{min_rate_dps:.0f} deg/s; expected {len(expected_nonzero)} non-zero runs "
            f"(axes {list(axes)} x rates {list(rates_dps)} deg/s); runs found: {listing()}"
        )
    for run, (ax_e, r_e) in zip(found, expected_nonzero):
        ratio = abs(run.rate_dps) / abs(r_e)
        # a clipped reading is a lower bound on the raw rate: only too high a reading refutes
        rate_ok = (
            ratio <= 1 + settings.scale_tol if run.clipped else abs(ratio - 1) <= settings.scale_tol
        )
        if run.axis != ax_e or np.sign(run.rate_dps) != np.sign(r_e) or not rate_ok:
            clip = " (clipped at the sensor range)" if run.clipped else ""
            raise ValueError(
                f"ratetable: run at {t[run.start]:.1f}-{t[run.end - 1]:.1f} s is about {run.axis} "
                f"at {run.rate_dps:+.0f} deg/s raw{clip}; expected {ax_e} {r_e:+g} deg/s (within "
                f"{settings.scale_tol:.0%}) by the table order; runs found: {listing()}"
            )
    it = iter(found)
    matched: list[ConstantRateRun | None] = [None if r == 0 else next(it) for _, r in expected]

    def steady_length(ax: str) -> int | None:
        """Median length (samples) of the unclipped runs of ``ax`` (else of all axes)."""
        for pool in (
            [m for (axm, _), m in zip(expected, matched) if m and axm == ax and not m.clipped],
            [m for m in matched if m and not m.clipped],
        ):
            if pool:
                return int(np.median([m.end - m.start for m in pool]))
        return None

    def centred(a: int, b: int, n: int | None) -> tuple[int, int]:
        if n is None or n >= b - a:
            return a, b
        a = a + (b - a - n) // 2
        return a, a + n

    rate = gyr - static.rest_at(t)
    rows = []
    for (ax, r), run in zip(expected, matched):
        if run is None:
            continue
        a, b = centred(run.start, run.end, steady_length(ax) if run.clipped else None)
        k = AXES.index(ax)
        turns = integrate_rate(t, rate, a, b)[k] / (2 * np.pi)
        rows.append(
            _row("ratetable", f"{ax}{int(r):+d}", "run", t, a, b, ax, r, int(np.sign(r)), turns)
        )
    for i, ((ax, r), run) in enumerate(zip(expected, matched)):
        if run is not None:
            continue
        lo = next((m.end for m in reversed(matched[:i]) if m is not None), 0)
        hi = next((m.start for m in matched[i + 1 :] if m is not None), t.size)
        between = [(a, b) for a, b in static.intervals if a >= lo and b <= hi]
        if not between:
            raise ValueError(
                f"ratetable: no static interval between {t[lo - 1] if lo else t[0]:.1f} s and "
                f"{t[hi - 1]:.1f} s for the {ax} 0 deg/s run; expected one between its neighbours"
            )
        a, b = max(between, key=lambda ab: ab[1] - ab[0])
        a, b = centred(a, b, steady_length(ax))  # as long as the steady plateaus of this axis
        rows.append(_row("ratetable", f"{ax}{int(r):+d}", "run", t, a, b, ax, r, 0, np.nan))
    out = _frame(rows).sort_values("start_s", kind="stable").reset_index(drop=True)
    rest = rest_note("ratetable", t, static)
    labels = {id(m): f"{ax}{int(r):+d}" for (ax, r), m in zip(expected, matched) if m}
    clipped = [labels[id(m)] for m in found if m.clipped]
    split = [labels[id(m)] for m in found if m.pieces > 1]
    messages = [rest.removeprefix("ratetable: ")] if rest else []
    if clipped:
        messages.append(
            f"run(s) {', '.join(clipped)} clipped at the gyroscope range (raw reading flat at the "
            "extreme): matched by the table order and nominal rate, cut to the median plateau of "
            "their axis; the rate-table fit leaves their saturated samples out"
        )
        logger.warning("ratetable: %s", messages[-1])
    if split:
        messages.append(
            f"run(s) {', '.join(split)} interrupted by a disturbance: the longest quiet piece kept"
        )
        logger.warning("ratetable: %s", messages[-1])
    out.attrs["notes"] = {"ratetable": "ratetable: " + "; ".join(messages)} if messages else {}
    return out


def segment_static(
    t_s: np.ndarray,
    acc: np.ndarray,
    gyr: np.ndarray,
    settings: DetectorSettings = DetectorSettings(),
) -> pd.DataFrame:
    """The static recording: one segment ``s01``, its longest static interval."""
    t, acc, gyr = _check_inputs(t_s, acc, gyr)
    static = find_static_intervals(t, acc, gyr, settings)
    a, b = max(static.intervals, key=lambda ab: ab[1] - ab[0])
    return _frame([_row("static", "s01", "static", t, a, b)])


def segment_poses(
    recording: str,
    t_s: np.ndarray,
    acc: np.ndarray,
    gyr: np.ndarray | None,
    settings: DetectorSettings = DetectorSettings(),
) -> pd.DataFrame:
    """Hand-placed static poses (``poses``, ``tumble``, ``ferraris`` without a section list).

    Every static interval becomes a segment of kind 'static' (``s01``, ``s02``, ...). Without a
    gyroscope (accelerometer-only loggers) quiet means a quiet accelerometer alone. When fewer
    than :data:`imucal.segments.holds.MIN_HOLDS` are found (poses held by hand: the tremor is above the
    noise), the holds of :func:`imucal.segments.holds.find_holds` replace them if it finds enough.

    Parameters
    ----------
    recording : str
    t_s : ndarray, shape (n,)
    acc : ndarray, shape (n, 3)
        m/s^2.
    gyr : ndarray, shape (n, 3) or None
        rad/s.
    settings : DetectorSettings

    Returns
    -------
    DataFrame
        Segments table rows; empty if the module never rests ``min_static_s``.
        ``attrs['notes']`` (recording -> message) says which detector gave the holds, and why,
        when the tremor-adaptive one was tried.
    """
    from imucal.segments.holds import (  # holds builds on this module
        MIN_HOLDS,
        find_holds,
        merge_overlapping,
    )

    if gyr is not None:
        t, acc, gyr = _check_inputs(t_s, acc, gyr)
        try:
            intervals = find_static_intervals(t, acc, gyr, settings).intervals
        except ValueError:
            intervals = []
    else:
        t, acc, _ = _check_inputs(t_s, acc, np.zeros_like(acc))
        intervals = find_quiet_intervals(t, acc, settings)
    merged = merge_overlapping(intervals)  # windows of one rest broken by a twitch: one pose
    notes, held_by_hand = {}, []
    if len(merged) < MIN_HOLDS:
        # the longest rest is the initial static interval of the method, when there is one
        base = max(merged, key=lambda ab: ab[1] - ab[0]) if merged else None
        adaptive = find_holds(t, acc, settings, base_interval=base)
        found = f"the noise-derived detector found {len(merged)} static interval(s), fewer than"
        if adaptive.multiple is not None:
            merged = adaptive.intervals
            held_by_hand = [recording]
            used = f"holds from the tremor-adaptive detector (Tedaldi 2014), {adaptive.describe()}"
        else:
            used = f"noise-derived intervals kept, tremor-adaptive detector: {adaptive.describe()}"
        notes[recording] = f"{recording}: {found} the {MIN_HOLDS} of the cube fit; {used}"
        logger.info(notes[recording])
    rows = [_row(recording, f"s{k:02d}", "static", t, a, b) for k, (a, b) in enumerate(merged, 1)]
    out = _frame(rows)
    out.attrs["notes"] = notes
    out.attrs["held_by_hand"] = held_by_hand
    return out


def manual_segments(recording: str, t_s: np.ndarray, entries: list[dict]) -> pd.DataFrame:
    """Segments given by hand in ``dataset.yaml`` for one recording.

    Parameters
    ----------
    recording : str
    t_s : ndarray, shape (n,)
        Timestamps of the ingested recording, s.
    entries : list of dict
        ``segments:`` entries of ``dataset.yaml`` naming this recording (keys ``label``, ``kind``,
        ``start_s``, ``end_s``, optional ``axis``, ``rate_dps``, ``up``, ``angle_deg``), or the
        entries of a section list (:func:`imucal.io.readers.read_sections`).

    Returns
    -------
    DataFrame
        Segments table rows; rows ``start_index`` .. ``end_index`` are the samples with
        ``start_s <= t_s <= end_s``. ``sense`` is 0 and ``turns`` NaN (not measured).

    Raises
    ------
    ValueError
        If an interval is empty, reversed or outside the recording, or a label repeats.
    """
    t = np.asarray(t_s, dtype=float)
    rows = []
    for e in entries:
        if e["kind"] not in KINDS:
            raise ValueError(
                f"manual segment {e['label']!r}: kind {e['kind']!r}, expected one of {KINDS}"
            )
        a = int(np.searchsorted(t, e["start_s"], side="left"))
        b = int(np.searchsorted(t, e["end_s"], side="right"))
        if not e["start_s"] < e["end_s"] or b - a < 2:
            raise ValueError(
                f"manual segment {recording}/{e['label']}: {e['start_s']}-{e['end_s']} s holds "
                f"{max(b - a, 0)} sample(s) of {t[0]:.2f}-{t[-1]:.2f} s; expected start_s < end_s "
                "and at least 2 samples inside the recording"
            )
        rate = e.get("rate_dps", np.nan)
        rows.append(
            _row(
                recording,
                e["label"],
                e["kind"],
                t,
                a,
                b,
                e.get("axis", ""),
                rate,
                up=e.get("up", ""),
                angle_deg=e.get("angle_deg", np.nan),
            )
        )
    frame = _frame(rows)
    dup = frame["label"][frame["label"].duplicated()].tolist()
    if dup:
        raise ValueError(
            f"manual segments of {recording}: label(s) {dup} repeat; expected unique labels"
        )
    return frame.sort_values("start_s", kind="stable").reset_index(drop=True)


def segment_recording(
    recording: str,
    table: pd.DataFrame,
    *,
    ratetable: dict | None = None,
    settings: DetectorSettings = DetectorSettings(),
) -> pd.DataFrame:
    """Automatic segments of one ingested recording (dispatch on its protocol name).

    Parameters
    ----------
    recording : str
        One of ``IMU_RECORDINGS``.
    table : DataFrame
        Ingested recording (``t_s``, ``acc_*``, ``gyr_*`` in SI units).
    ratetable : dict, optional
        ``{'axes': [...], 'rates_dps': [...]}``; required for ``ratetable``.
    settings : DetectorSettings

    Returns
    -------
    DataFrame
        Segments table rows of this recording.
    """
    if recording not in IMU_RECORDINGS + OTHER_RECORDINGS:
        raise ValueError(
            f"recording {recording!r}: expected one of {IMU_RECORDINGS + OTHER_RECORDINGS}"
        )
    if recording in OTHER_RECORDINGS:
        return _segment_pose_recording(recording, table, settings)
    missing = [c for c in (*ACC, *GYR) if c not in table.columns]
    if missing:
        raise ValueError(
            f"{recording}: no column(s) {missing}; the automatic segmentation needs the "
            "accelerometer and the gyroscope (give a section list or manual segments instead)"
        )
    t = table[TIME].to_numpy(dtype=float)
    acc = table[list(ACC)].to_numpy(dtype=float)
    gyr = table[list(GYR)].to_numpy(dtype=float)
    # streams merged on time leave rows without an acc/gyr sample (NaN): segment the rows with
    # both, then give the indices in rows of the whole table
    rows = np.flatnonzero(np.isnan(acc).all(axis=1) | np.isnan(gyr).all(axis=1))
    keep = np.setdiff1d(np.arange(t.size), rows) if rows.size else None
    if keep is not None:
        t, acc, gyr = t[keep], acc[keep], gyr[keep]
    if recording == "rotation3d":
        out = segment_rotation3d(t, acc, gyr, settings)
    elif recording == "cube":
        out = segment_cube(t, acc, gyr, settings)
    elif recording == "static":
        out = segment_static(t, acc, gyr, settings)
    elif ratetable is None:
        raise ValueError("recording 'ratetable' needs the table's axes and rates_dps; got none")
    else:
        out = segment_ratetable(t, acc, gyr, ratetable["axes"], ratetable["rates_dps"], settings)
    return out if keep is None else _to_table_rows(out, keep)


def _segment_pose_recording(
    recording: str, table: pd.DataFrame, settings: DetectorSettings
) -> pd.DataFrame:
    """Static poses of a recording with an accelerometer (and maybe a gyroscope), else none."""
    if not all(c in table.columns for c in ACC):
        return _frame([])  # magnetometer-only: nothing rests in a way we can tell
    has_gyr = all(c in table.columns for c in GYR)
    cols = list(ACC) + (list(GYR) if has_gyr else [])
    values = table[cols].to_numpy(dtype=float)
    keep = np.flatnonzero(np.isfinite(values).all(axis=1))
    t = table[TIME].to_numpy(dtype=float)[keep]
    acc = values[keep, :3]
    gyr = values[keep, 3:] if has_gyr else None
    return _to_table_rows(segment_poses(recording, t, acc, gyr, settings), keep)


def _to_table_rows(out: pd.DataFrame, keep: np.ndarray) -> pd.DataFrame:
    """Segment row indices into the kept rows -> indices into the whole table (end exclusive)."""
    if len(out):
        out["start_index"] = keep[out["start_index"].to_numpy()]
        out["end_index"] = keep[out["end_index"].to_numpy() - 1] + 1
    return out


def segment_dataset(
    tables: dict[str, pd.DataFrame],
    *,
    ratetable: dict | None = None,
    manual: list[dict] | None = None,
    window_s: float = 0.5,
    p_false: float = 1e-6,
    min_static_s: float = 1.0,
    rest_tol_dps: float = 2.0,
    scale_tol: float = 0.2,
    rest_drift_dps_per_s: float = 0.02,
    fallback: bool = False,
) -> pd.DataFrame:
    """The segments table of a dataset: automatic, or manual for recordings named in ``manual``.

    Parameters
    ----------
    tables : dict of str to DataFrame
        Ingested IMU recordings by name (``rotation3d``, ``cube``, ``ratetable``, ``static``).
    ratetable : dict, optional
        ``Dataset.ratetable``.
    manual : list of dict, optional
        ``Dataset.segments``: replaces the automatic segments of every recording it names.
    window_s, p_false, min_static_s, rest_tol_dps, scale_tol, rest_drift_dps_per_s
        See ``DetectorSettings``.
    fallback : bool
        For partial sessions: a recording whose protocol is not found (e.g. hand-held turns
        without the rests the rotation3d matching needs) keeps only its static poses, and the
        reason goes to ``attrs['notes']`` (recording -> message) instead of an error.

    Returns
    -------
    DataFrame
        Columns ``SEGMENT_COLUMNS``, recordings in protocol order, segments in time order.
        ``attrs['notes']`` (recording -> message): the fallbacks, and the rate-table runs found
        clipped at the sensor range or split by a disturbance (:func:`segment_ratetable`).
        ``attrs['held_by_hand']``: recordings whose holds came from the tremor-adaptive
        detector (:mod:`imucal.segments.holds`): held by hand, not at rest.
    """
    settings = DetectorSettings(
        window_s, p_false, min_static_s, rest_tol_dps, scale_tol, rest_drift_dps_per_s
    )
    manual = list(manual or [])
    unknown = sorted({e["recording"] for e in manual} - set(tables))
    if unknown:
        raise ValueError(
            f"manual segments name recording(s) {unknown}; the dataset has {sorted(tables)}"
        )
    frames, notes, held_by_hand = [], {}, []
    for name in [r for r in IMU_RECORDINGS if r in tables] + sorted(
        set(tables) - set(IMU_RECORDINGS)
    ):
        mine = [e for e in manual if e["recording"] == name]
        t = tables[name][TIME].to_numpy(dtype=float)
        if mine:
            frames.append(manual_segments(name, t, mine))
            continue
        try:
            frames.append(
                segment_recording(name, tables[name], ratetable=ratetable, settings=settings)
            )
            notes.update(frames[-1].attrs.get("notes", {}))
        except ValueError as err:
            if not fallback:
                raise
            notes[name] = f"{name}: automatic segmentation failed ({err}); static poses only"
            logger.warning(notes[name])
            frames.append(_segment_pose_recording(name, tables[name], settings))
        held_by_hand += frames[-1].attrs.get("held_by_hand", [])
        logger.info("%s: %d segments", name, len(frames[-1]))
    out = pd.concat(frames, ignore_index=True) if frames else _frame([])
    out.attrs["notes"] = notes
    out.attrs["held_by_hand"] = held_by_hand
    return out
