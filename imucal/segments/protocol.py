"""Segmenters of the protocol recordings without a rate table: rotation3d phases, cube
positions, the static recording, hand-placed poses.

Each takes a recording's timestamps, accelerometer and gyroscope (raw SI) and returns segments
table rows (:mod:`imucal.segments.table`), with notes in ``attrs['notes']``; the static detector
is :mod:`imucal.segments.detector`.

**Rotation3d phases** are the motions the detector classifies as full turns, matched to the
protocol's order of axes x, y, z (see :mod:`imucal.segments.detector`, *Motions*).

**Cube positions** are static intervals; consecutive ones whose mean specific force points the
same way (within half the 45-degree V-block step, 22.5 deg) are one position (a yaw about the
vertical does not give the cube fit a new point): the longest is kept, the others are labelled
``static``. A cube turned by hand rests with tremor above the noise: when the static intervals
give fewer positions than the fit needs, the holds of the tremor-adaptive detector
(:func:`imucal.segments.holds.find_holds`) are grouped the same way, and the notes say so.
"""

from __future__ import annotations

import logging

import numpy as np
import pandas as pd

from imucal.columns import AXES
from imucal.segments.detector import (
    DetectorSettings,
    Motion,
    check_inputs,
    find_motions,
    find_quiet_intervals,
    find_static_intervals,
    is_clipped,
    rest_note,
)
from imucal.segments.holds import MIN_HOLDS, find_holds, merge_overlapping
from imucal.segments.table import segment_row, segments_frame

logger = logging.getLogger(__name__)


#: Half the 45-deg step between cube positions: gravity directions closer than this are one.
SAME_POSITION_DEG = 22.5


def _describe(t: np.ndarray, m: Motion) -> str:
    return (
        f"about {m.axis} {np.degrees(m.angle_rad[AXES.index(m.axis)]):+.0f} deg raw "
        f"({m.raw_turns:+.2f} turns) at {t[m.start]:.1f}-{t[m.end - 1]:.1f} s"
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
    t, acc, gyr = check_inputs(t_s, acc, gyr)
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
        segment_row("rotation3d", f"s{i:02d}", "static", t, a, b)
        for i, (a, b) in enumerate(static.intervals, start=1)
    ]
    n_transition = 0
    for m in motions:
        if m in phases:
            k = np.nan if m in clipped else _full_turns(m.raw_turns, settings.scale_tol)
            sense = int(np.sign(m.raw_turns))
            rows.append(
                segment_row(
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
                segment_row(
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
    out = segments_frame(rows).sort_values("start_s", kind="stable").reset_index(drop=True)
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
    t, acc, gyr = check_inputs(t_s, acc, gyr)
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
                rows.append(segment_row("cube", f"p{i:02d}", "position", t, a, b))
            else:
                n_static += 1
                rows.append(segment_row("cube", f"s{n_static:02d}", "static", t, a, b))
    out = segments_frame(rows).sort_values("start_s", kind="stable").reset_index(drop=True)
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


def segment_static(
    t_s: np.ndarray,
    acc: np.ndarray,
    gyr: np.ndarray,
    settings: DetectorSettings = DetectorSettings(),
) -> pd.DataFrame:
    """The static recording: one segment ``s01``, its longest static interval."""
    t, acc, gyr = check_inputs(t_s, acc, gyr)
    static = find_static_intervals(t, acc, gyr, settings)
    a, b = max(static.intervals, key=lambda ab: ab[1] - ab[0])
    return segments_frame([segment_row("static", "s01", "static", t, a, b)])


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
    if gyr is not None:
        t, acc, gyr = check_inputs(t_s, acc, gyr)
        try:
            intervals = find_static_intervals(t, acc, gyr, settings).intervals
        except ValueError:
            intervals = []
    else:
        t, acc, _ = check_inputs(t_s, acc, np.zeros_like(acc))
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
    rows = [
        segment_row(recording, f"s{k:02d}", "static", t, a, b) for k, (a, b) in enumerate(merged, 1)
    ]
    out = segments_frame(rows)
    out.attrs["notes"] = notes
    out.attrs["held_by_hand"] = held_by_hand
    return out
