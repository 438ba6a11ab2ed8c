"""Segmenter of the rate-table recording: constant-rate runs matched to the table's axes and
rates.

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

import logging
from dataclasses import dataclass

import numpy as np
import pandas as pd

from imucal.columns import AXES
from imucal.segments.detector import (
    DetectorSettings,
    StaticIntervals,
    at_extreme,
    check_inputs,
    find_quiet_intervals,
    find_static_intervals,
    integrate_rate,
    rest_note,
)
from imucal.segments.table import segment_row, segments_frame

logger = logging.getLogger(__name__)


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
    t, acc, gyr = check_inputs(t_s, acc, gyr)
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
            segment_row(
                "ratetable", f"{ax}{int(r):+d}", "run", t, a, b, ax, r, int(np.sign(r)), turns
            )
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
        rows.append(segment_row("ratetable", f"{ax}{int(r):+d}", "run", t, a, b, ax, r, 0, np.nan))
    out = segments_frame(rows).sort_values("start_s", kind="stable").reset_index(drop=True)
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
