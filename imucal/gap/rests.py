"""The gap diagnosis of a partial session on its short rests, pooled.

A partial session with neither a static recording, nor an orientation reference, nor declared
static poses (:func:`imucal.gap.composite.partial_scope`) still rests between its motions: the
faces of a Ferraris session, the holds of a tumble. One rest of 40 s is scored as a static
recording (:func:`imucal.gap.composite.rest_as_static`); shorter ones cannot carry the static
statistics (an Allan deviation at 10 s needs halves of 20 s), but together they carry the
statistics a few seconds support. This module scores them as one part, ``rests``:

* **rests**: every ``static`` or ``position`` segment of at least :data:`MIN_SHORT_REST_S`
  (:func:`session_rests`), each a short static recording of one or two streams
  (:mod:`imucal.gap.streams`);
* **twin** (:class:`RestsTwin`): each rest replayed by the static twin
  (:func:`imucal.gap.statictwin.render_static`) at its own sample count, rate and mean reading
  per axis, with one noise per sensor for the whole session (:func:`pooled_white`): white per
  axis from the first differences pooled over the rests, the rounding taken out at each
  rest's own level, the quantisation step from ``dataset.yaml`` or the readings. Coloured
  terms are not drawn: rests of a few seconds do not resolve a bias wander, and the twin says
  so in its notes; what such a wander does inside a rest is scored (the Allan excess at
  :data:`ALLAN_TAU_S` and the trend) and read as the twin's shortfall when it departs;
* **statistics** (:func:`rests_statistics`), pooled over the rests: per sensor axis the white
  noise level, the fraction of first differences that are 0 (the quantisation against the
  noise), the Allan deviation at :data:`ALLAN_TAU_S` as a log-ratio to the white line and the
  trend within the rests; per stream the receive latency above each rest's lower envelope and
  the fractions of bursts and long gaps;
* **halves**: A is the first half of every rest in time, B the second;
* **library**: ``timing_jitter``, the static recording's signature with its estimator on the
  rests' own lengths (the specs' models of scope ``rests``,
  :func:`imucal.gap.library.scope_library`); the others are listed with the reason
  (:func:`imucal.gap.library.not_observable`).

Scoring is the null of every scope (:func:`imucal.gap.scoring.scored_diagnosis`).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from imucal.columns import AXES, SENSOR_COLUMNS
from imucal.constants import STANDARD_GRAVITY_M_S2
from imucal.gap.library import not_observable, scope_library
from imucal.gap.locations import allan_deviation
from imucal.gap.scoring import DiagnosisSettings, scope_diagnosis
from imucal.gap.statictwin import build_static_twin, quantum, render_static
from imucal.gap.statistics import HALVES
from imucal.gap.streams import Stream, receive_latency, split_streams
from imucal.gap.twin import Replica
from imucal.noise.process import NoiseProcess, quantised_variance
from imucal.segments.table import rows_of

#: Shortest rest pooled (s): each half holds three averaging times of :data:`ALLAN_TAU_S`.
MIN_SHORT_REST_S = 3.0
#: Averaging time of the rests' Allan statistic (s).
ALLAN_TAU_S = 0.5


def session_rests(
    tables: Mapping[str, pd.DataFrame],
    segments: pd.DataFrame,
    min_duration_s: float = MIN_SHORT_REST_S,
) -> tuple[dict[str, dict[str, Stream]], str]:
    """The rests of a session long enough to be pooled, as streams.

    Parameters
    ----------
    tables : mapping of str to DataFrame
        Ingested recordings by name.
    segments : DataFrame
        The segments table; its ``static`` and ``position`` rows are the rests.
    min_duration_s : float
        Shortest rest pooled (s).

    Returns
    -------
    rests : dict
        ``"{recording}/{label}"`` -> streams of the rest (:func:`imucal.gap.streams.split_streams`:
        a stream needs 100 samples), in recording and time order; empty when none qualifies.
    source : str
        Which rests they are (count, total and range of durations), or why there are none.
    """
    rests, durations, found, unturned = {}, [], 0, []
    for name, table in tables.items():
        t = table["t_s"].to_numpy(dtype=float)
        held = {
            s for s, cols in SENSOR_COLUMNS.items()
            if all(c in table.columns and table[c].notna().any() for c in cols)
        }  # fmt: skip
        # rests found by the accelerometer alone
        gyroscope = "gyr" in held or "acc" not in held
        if not gyroscope and "mag" in held:
            unturned.append(name)
        for row in (
            rows_of(segments, name, "static", "position").sort_values("start_s").itertuples()
        ):
            found += 1
            duration = float(row.end_s) - float(row.start_s)
            if duration < min_duration_s:
                continue
            part = table[(t >= float(row.start_s)) & (t <= float(row.end_s))]
            streams = split_streams(part.reset_index(drop=True))
            if not gyroscope:
                streams.pop("mag", None)
            if streams:
                rests[f"{name}/{row.label}"] = streams
                durations.append(duration)
    if not rests:
        return rests, (
            f"none of the {found} rests found is {min_duration_s:g} s long with 100 samples"
            if found
            else "no rest was found"
        )
    source = (
        f"{len(rests)} rests of {min(durations):.1f}-{max(durations):.1f} s "
        f"({sum(durations):.1f} s in all; {found - len(rests)} shorter ones left out)"
    )
    if unturned:
        source += (
            f"; the magnetometer of {', '.join(unturned)} is left out: without a gyroscope its "
            "rests are found by the accelerometer alone, which does not see a turn about the "
            "vertical, and such a turn moves the field"
        )
    return rests, source


def pooled_white(parts: list[np.ndarray], step: float) -> np.ndarray:
    """White-noise std per axis before rounding, shared by rests at different levels.

    Parameters
    ----------
    parts : list of ndarray, each shape (n_i, 3)
        The rests' readings of one sensor (SI).
    step : float
        Quantisation step (SI per count); 0 for readings that are not rounded.

    Returns
    -------
    ndarray, shape (3,)
        The smallest std whose rounded readings, each rest at its own mean, have on average
        (weighted by the rests' differences) the rests' pooled white variance, half the mean
        square of their first differences (:func:`imucal.noise.process.quantised_variance`).
    """
    diffs = [np.diff(p, axis=0) for p in parts]
    weights = np.array([len(d) for d in diffs], dtype=float)
    target = np.sum([np.sum(d**2, axis=0) for d in diffs], axis=0) / weights.sum() / 2
    out = np.zeros(3)
    for j in range(3):
        if target[j] <= 0:
            continue
        if step <= 0 or target[j] >= step**2 * (9 + 1 / 12):
            out[j] = np.sqrt(max(target[j] - (step**2 / 12 if step > 0 else 0.0), 0.0))
            continue
        levels = [float(np.mean(p[:, j])) for p in parts]
        grid = step * np.geomspace(1e-3, 3.0, 400)
        var = np.array(
            [
                np.dot(weights, [quantised_variance(s, step, u) for u in levels]) / weights.sum()
                for s in grid
            ]
        )
        out[j] = float(grid[np.argmax(var >= target[j])])
    return out


def pooled_walk(parts: list[np.ndarray], rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """A bias random walk per axis when the rests' pooled Allan deviation at
    :data:`ALLAN_TAU_S` resolves an excess over their white line, else 0.

    Parameters
    ----------
    parts : list of ndarray, each shape (n_i, 3)
        The rests' readings of one sensor (SI).
    rate_hz : float
        Their sample rate (Hz).

    Returns
    -------
    walk : ndarray, shape (3,)
        ``K`` (SI / sqrt(s)) whose Allan variance ``K^2 tau / 3`` is the excess, where the
        excess is above two standard errors of the pooled Allan variance; 0 elsewhere.
    ratio : ndarray, shape (3,)
        Pooled Allan variance over the white line (1 for white noise).

    Notes
    -----
    The standard error is that of an overlapping Allan variance of white noise with
    ``1.5 n_i / m`` equivalent degrees of freedom per rest (``m`` samples per averaging time),
    summed over the rests. A walk is the simplest term that adds Allan variance at the scored
    averaging time and a trend within a rest; which coloured process it really is, rests of a
    few seconds do not tell.
    """
    m = max(int(round(ALLAN_TAU_S * rate_hz)), 1)
    av, white, w, dof = np.zeros(3), np.zeros(3), 0.0, 0.0
    for x in parts:
        if len(x) < 2 * m + 1:
            continue
        k = len(x) - 2 * m
        av += k * allan_deviation(x, m) ** 2
        white += k * np.mean(np.diff(x, axis=0) ** 2, axis=0) / 2 / m
        w += k
        dof += 1.5 * len(x) / m
    if not w or not np.all(white > 0):
        return np.zeros(3), np.ones(3)
    ratio = av / white
    resolved = ratio - 1 > 2 * np.sqrt(2 / dof)
    excess = np.where(resolved, (av - white) / w, 0.0)
    return np.sqrt(3 * excess / (m / rate_hz)), ratio


@dataclass(frozen=True)
class RestsTwin:
    """The twin of a session's pooled rests: one static twin per rest, one noise per sensor.

    Attributes
    ----------
    rests : dict
        ``"{recording}/{label}"`` -> :class:`~imucal.gap.statictwin.StaticTwin` of the rest (its
        streams' sample counts and rates, its mean reading, the session's noise).
    notes : list of str
    """

    rests: dict
    notes: list = field(default_factory=list)

    def describe(self) -> dict:
        """JSON-ready summary."""
        first = next(iter(self.rests.values()))
        return {
            "rests": {
                name: {
                    k: {"samples": int(n), "rate_hz": float(r)} for k, (n, r) in tw.streams.items()
                }
                for name, tw in self.rests.items()
            },
            "noise_process": {k: p.describe() for k, p in first.noise.items()},
            "sensitivity": {k: float(v) for k, v in first.sensitivity.items()},
            "duration_s": float(sum(tw.duration_s for tw in self.rests.values())),
            "notes": list(self.notes),
        }

    def replica(self, seed: int, effects: tuple = (), halves: tuple = HALVES) -> Replica:
        """Render every rest with its own random streams (seed ``seed * 1000 + i`` for the
        ``i``-th rest) and measure the pooled statistics on ``halves``."""
        session = {}
        for i, (name, twin) in enumerate(self.rests.items()):
            for stream, st in render_static(twin, seed * 1000 + i, effects).items():
                session[f"{name}/{stream}"] = st
        return Replica(seed, session, {h: rests_statistics(session, h) for h in halves})


def flat_streams(rests: Mapping[str, Mapping[str, Stream]]) -> dict[str, Stream]:
    """``"{rest}/{stream}"`` -> Stream: the form the statistics and estimators read."""
    return {f"{name}/{k}": st for name, streams in rests.items() for k, st in streams.items()}


def build_rests_twin(
    rests: Mapping[str, Mapping[str, Stream]],
    calibration: Mapping | None,
    sensitivity: Mapping[str, float],
    gravity_m_s2: float,
) -> RestsTwin:
    """The twin of a session's rests (module docstring).

    Parameters
    ----------
    rests : dict
        Output of :func:`session_rests` (at least one rest).
    calibration, sensitivity, gravity_m_s2
        As in :func:`imucal.gap.statictwin.build_static_twin`.

    Returns
    -------
    RestsTwin

    Raises
    ------
    ValueError
        If there is no rest.
    """
    if not rests:
        raise ValueError("the rests' twin needs at least one rest, got none")
    parts: dict[str, list] = {}
    rates: dict[str, list] = {}
    for streams in rests.values():
        for st in streams.values():
            for s, x in st.values.items():
                parts.setdefault(s, []).append(x)
                rates.setdefault(s, []).append(st.rate_hz)
    notes, processes, steps = [], {}, {}
    for s, xs in parts.items():
        q = float(sensitivity.get(s) or quantum(np.vstack(xs)))
        if not sensitivity.get(s):
            notes.append(f"{s}: quantisation step {q:.4g} SI estimated from the readings")
        walk, ratio = pooled_walk(xs, float(np.median(rates[s])))
        zero = np.zeros(3)
        processes[s] = NoiseProcess(pooled_white(xs, q), zero, np.ones(3), walk, q)
        steps[s] = q
        resolved = [a for a, k in zip(AXES, walk, strict=True) if k > 0]
        notes.append(
            f"{s}: Allan variance at {ALLAN_TAU_S:g} s {', '.join(f'{r:.2f}' for r in ratio)} "
            "x the white line; "
            + (
                f"a bias random walk is drawn on {', '.join(resolved)} (resolved at two "
                "standard errors)"
                if resolved
                else "no coloured term is resolved"
            )
        )
    notes.append(
        "noise: the session's own per axis: white from the first differences pooled over "
        f"{len(rests)} rests with the rounding taken out at each rest's level; a coloured term "
        f"only where the rests' Allan variance at {ALLAN_TAU_S:g} s resolves one (a bias random "
        "walk standing in for it: rests of a few seconds do not tell which process it is)"
    )
    notes.append("each rest at its own sample count, rate and mean reading; regular sample times")
    longest = max(rests.values(), key=lambda st: max(len(s.t_s) for s in st.values()))
    base = build_static_twin(longest, calibration, steps, gravity_m_s2)
    notes = [n for n in base.notes if "fitted calibration" in n] + notes
    twins = {}
    for name, streams in rests.items():
        twins[name] = dataclasses.replace(
            base,
            streams={k: (len(st.t_s), st.rate_hz) for k, st in streams.items()},
            temperature=None,
            noise=dict(processes),
            level={s: x.mean(axis=0) for st in streams.values() for s, x in st.values.items()},
            notes=[],
        )
    return RestsTwin(twins, notes)


def rests_statistics(session: Mapping[str, Stream], half: str | None = None) -> dict:
    """The pooled statistics of a session's rests (module docstring).

    Parameters
    ----------
    session : dict
        ``"{rest}/{stream}"`` -> Stream (:func:`flat_streams`, or a replica's session).
    half : {None, 'A', 'B'}
        The whole rests, or the first / second half of every rest in time.

    Returns
    -------
    dict
        ``(stage, sensor, axis, "rests", statistic)`` -> value: ``ingest/clock/{imu,mag}``
        ``stamp_scatter_s`` (s), ``burst_fraction``, ``long_gap_fraction``;
        ``noise/{sensor}/{axis}`` ``rest_noise`` (SI), ``rest_still_fraction``,
        ``rest_adev_excess`` (log ratio at :data:`ALLAN_TAU_S`), ``rest_trend_per_s`` (SI/s).
    """
    timing: dict = {}
    noise: dict = {}
    for key, stream in session.items():
        kind = key.rsplit("/", 1)[-1]
        st = stream.half(half)
        rate = st.rate_hz
        lat, _ = receive_latency(st.t_s, rate)
        tm = timing.setdefault(kind, {"lat2": 0.0, "n": 0, "burst": 0, "long": 0, "d": 0})
        d = np.diff(st.t_s) * rate
        tm["lat2"] += float(np.sum(lat**2))
        tm["n"] += len(lat)
        tm["burst"] += int(np.sum(d < 0.25))
        tm["long"] += int(np.sum(d > 3.0))
        tm["d"] += len(d)
        m = max(int(round(ALLAN_TAU_S * rate)), 1)
        for s, x in st.values.items():
            acc = noise.setdefault(
                s, {"d2": np.zeros(3), "nd": 0, "still": np.zeros(3), "av": np.zeros(3),
                    "nav": 0, "av_white": np.zeros(3), "sxy": np.zeros(3), "sxx": 0.0},
            )  # fmt: skip
            dx = np.diff(x, axis=0)
            acc["d2"] += np.sum(dx**2, axis=0)
            acc["nd"] += len(dx)
            acc["still"] += np.sum(dx == 0, axis=0)
            if len(x) >= 2 * m + 1:
                w = len(x) - 2 * m
                acc["av"] += w * allan_deviation(x, m) ** 2
                # the white line at this rest's averaging: sigma^2 / m
                acc["av_white"] += w * np.mean(dx**2, axis=0) / 2 / m
                acc["nav"] += w
            tk = np.arange(len(x)) / rate
            tk = tk - tk.mean()
            acc["sxy"] += tk @ (x - x.mean(axis=0))
            acc["sxx"] += float(tk @ tk)
    out = {}
    for kind, tm in timing.items():
        key = ("ingest", "clock", kind, "rests")
        out[(*key, "stamp_scatter_s")] = float(max(np.sqrt(tm["lat2"] / tm["n"]), 1e-7))
        out[(*key, "burst_fraction")] = tm["burst"] / tm["d"]
        out[(*key, "long_gap_fraction")] = tm["long"] / tm["d"]
    for s, acc in noise.items():
        white = np.sqrt(acc["d2"] / acc["nd"] / 2)
        for j, a in enumerate(AXES):
            key = ("noise", s, a, "rests")
            out[(*key, "rest_noise")] = float(max(white[j], 1e-300))
            out[(*key, "rest_still_fraction")] = float(acc["still"][j] / acc["nd"])
            if acc["nav"] and acc["av_white"][j] > 0 and acc["av"][j] > 0:
                out[(*key, "rest_adev_excess")] = float(
                    0.5 * np.log(acc["av"][j] / acc["av_white"][j])
                )
            out[(*key, "rest_trend_per_s")] = float(acc["sxy"][j] / acc["sxx"])
    return out


def diagnose_rests(
    rests: Mapping[str, Mapping[str, Stream]],
    *,
    rests_source: str,
    dataset: str,
    calibration: Mapping | None = None,
    sensitivity: Mapping[str, float] | None = None,
    gravity_m_s2: float = STANDARD_GRAVITY_M_S2,
    settings: DiagnosisSettings = DiagnosisSettings(),
) -> dict:
    """The gap diagnosis of a partial session on its pooled short rests.

    Parameters
    ----------
    rests : dict
        Output of :func:`session_rests` (at least one rest).
    rests_source : str
        Which rests they are (:func:`session_rests`); kept in the result as ``static_source``.
    dataset : str
    calibration, sensitivity, gravity_m_s2, settings
        As in :func:`imucal.gap.static.diagnose_static`; ``exclude`` leaves effects out of
        the rests' library.

    Returns
    -------
    dict
        diagnosis.json (:func:`~imucal.gap.scoring.scored_diagnosis`) plus ``scope``
        (``rests``), ``static_source``, ``not_observable``, ``twin``, ``settings``,
        ``timing_s``.

    Raises
    ------
    ValueError
        If there is no rest.
    """
    t0 = time.perf_counter()
    twin = build_rests_twin(rests, calibration, dict(sensitivity or {}), gravity_m_s2)
    session = flat_streams(rests)
    stats = {h: rests_statistics(session, h) for h in HALVES}
    return scope_diagnosis(
        twin, session, stats, scope_library("rests"), scope="rests",
        static_source=rests_source, not_observable=not_observable("rests"),
        cannot_show="the rests cannot show this effect (no such stream)",
        dataset=dataset, settings=settings, started=t0,
    )  # fmt: skip
