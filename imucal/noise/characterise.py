"""The noise stage: Allan deviation and IEEE 952 terms of every axis of a static recording.

The recording is read one column at a time through a reader the caller gives (the rule passes
:func:`imucal.io.read_recording_column`), so the memory held is one column's phase and a fixed
chunk (:mod:`imucal.noise.allan`), whatever the number of columns.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence

import numpy as np

from imucal.columns import AXES, SENSOR_COLUMNS, SI_UNITS, TIME
from imucal.noise.allan import overlapping_adev
from imucal.noise.fit import TERMS, fit_noise_terms

logger = logging.getLogger(__name__)

#: Version of the noise.json format written by :func:`characterise_noise`.
FORMAT_VERSION = 1
#: Largest relative difference of the mean and the median time step for which the stamps count
#: as regular (a few lost packets) and the rate is taken from the median step.
REGULAR_TOLERANCE = 0.1
MODEL = (
    "sigma^2(tau) = 3 Q^2/tau^2 + N^2/tau + (2 ln2/pi) B^2 + K^2 tau/3 "
    "(IEEE Std 952-1997 Annex C; IEEE Std 1293-1998)"
)


def characterise_noise(
    read_column: Callable[[str], np.ndarray],
    columns: Sequence[str],
    *,
    recording: str,
    window_s: Sequence[float] | None,
    min_duration_s: float,
    level: float,
) -> dict:
    """Allan deviation, confidence interval and fitted noise terms of each sensor axis.

    Parameters
    ----------
    read_column : callable
        ``read_column(name) -> ndarray, shape (n,)``: one column of the recording (SI units).
    columns : sequence of str
        The recording's column names; the sensors whose three columns are all present are
        analysed, each on the rows where it was sampled (its first column finite).
    recording : str
        Name of the recording (for the record).
    window_s : (start, end) or None
        Part of the recording to analyse, s on its ``t_s`` axis; None for all of it.
    min_duration_s : float
        Shortest analysable span, s.
    level : float
        Two-sided confidence level of the intervals (0.683 for one sigma).

    Returns
    -------
    dict
        The ``noise.json`` content: ``format_version``, ``recording``, ``rate_hz``,
        ``duration_s``, ``n_samples``, ``level``, ``model`` and ``sensors`` (per sensor
        ``unit``, ``rate_hz``, ``n_samples``, ``timing`` and per axis the
        :meth:`imucal.noise.fit.NoiseFit.to_dict`), plus ``skipped`` (sensor -> reason).
        ``rate_hz`` is the gyroscope's (else the first analysed sensor's).

    Raises
    ------
    ValueError
        If the span is shorter than ``min_duration_s``, the time axis is not increasing, or no
        sensor could be analysed (the stage then writes its not-run record).
    """
    t = read_column(TIME)
    start, stop = _window(t, window_s)
    t = t[start:stop]
    span_s = float(t[-1] - t[0]) if len(t) > 1 else 0.0
    if span_s < min_duration_s:
        raise ValueError(
            f"recording {recording!r} spans {span_s:.1f} s in the window {window_s}; "
            f"the noise stage needs at least {min_duration_s} s"
        )
    if not np.all(np.diff(t) > 0):
        raise ValueError(f"recording {recording!r}: t_s is not strictly increasing")

    sensors, skipped = {}, {}
    for sensor, names in SENSOR_COLUMNS.items():
        if not set(names) <= set(columns):
            continue
        try:
            sensors[sensor] = _sensor_noise(read_column, names, t, start, stop, level)
        except _Skip as why:
            skipped[sensor] = str(why)
            logger.info("noise: %s skipped: %s", sensor, why)
    if not sensors:
        raise ValueError(
            f"recording {recording!r}: no sensor with three complete columns to analyse"
            + (f" ({skipped})" if skipped else "")
        )
    # the rate the tools are told: the gyroscope's (the IMU's packet rate)
    rate_hz = sensors.get("gyr", next(iter(sensors.values())))["rate_hz"]
    return {
        "format_version": FORMAT_VERSION,
        "recording": recording,
        "window_s": None if window_s is None else [float(w) for w in window_s],
        "rate_hz": rate_hz,
        "duration_s": span_s,
        "n_samples": int(stop - start),
        "level": level,
        "model": MODEL,
        "terms": list(TERMS),
        "sensors": sensors,
        "skipped": skipped,
    }


class _Skip(Exception):
    """A sensor that cannot be analysed (the reason goes into ``skipped``)."""


def _sensor_noise(
    read_column: Callable[[str], np.ndarray],
    names: Sequence[str],
    t: np.ndarray,
    start: int,
    stop: int,
    level: float,
) -> dict:
    """Allan deviation and fits of one sensor's axes, on the rows where it was sampled.

    A sensor merged from its own stream (another rate, its own receive stamps) is sampled on
    some rows only: its samples are the rows where its first column is finite, with their
    own time stamps and rate.
    """
    rows = np.isfinite(read_column(names[0])[start:stop])
    # on every row (the usual case) slices, not copies, keep the memory at one column
    every_row = bool(rows.all())
    pick = slice(None) if every_row else rows
    if int(rows.sum()) < 2:
        raise _Skip(f"{names[0]} has fewer than 2 samples")
    dt = np.diff(t[pick])
    # Equal spacing is assumed. Regular stamps with lost packets: the rate of the median step
    # (the samples that remain are that far apart); irregular receive stamps (bursts): the
    # mean rate. Which one, and the spread of the stamps, go on record.
    median_dt, mean_dt = float(np.median(dt)), float(np.mean(dt))
    regular = abs(mean_dt / median_dt - 1) < REGULAR_TOLERANCE
    rate_hz = 1.0 / median_dt if regular else 1.0 / mean_dt
    timing = {"median_dt_s": median_dt, "mean_dt_s": mean_dt, "max_dt_s": float(np.max(dt)),
              "rate_from": "median step" if regular else "mean step (irregular stamps)"}  # fmt: skip
    del dt
    axes = {}
    for axis, name in zip(AXES, names):
        y = read_column(name)[start:stop][pick]
        if not np.all(np.isfinite(y)):
            raise _Skip(f"{name} lacks samples on rows where {names[0]} has them")
        if np.ptp(y) == 0:
            raise _Skip(f"{name} is constant")
        axes[axis] = fit_noise_terms(overlapping_adev(y, rate_hz), level=level)
    sensor = next(s for s, cols in SENSOR_COLUMNS.items() if tuple(cols) == tuple(names))
    unit = SI_UNITS[sensor]
    return {
        "unit": unit,
        "rate_hz": float(rate_hz),
        "n_samples": int(rows.sum()),
        "timing": timing,
        "axes": {a: f.to_dict(unit) for a, f in axes.items()},
    }


def _window(t: np.ndarray, window_s: Sequence[float] | None) -> tuple[int, int]:
    if window_s is None:
        return 0, len(t)
    lo, hi = (float(w) for w in window_s)
    if not lo < hi:
        raise ValueError(f"noise window {window_s}: start must be before end")
    return int(np.searchsorted(t, lo, side="left")), int(np.searchsorted(t, hi, side="right"))


def sensor_noise(noise: dict, sensor: str, term: str) -> tuple[float | None, bool]:
    """The largest value of a term over a sensor's axes, and whether every axis resolved it.

    For an axis that does not resolve the term its upper bound stands in (so the value is
    never smaller than what the recording allows).

    Returns
    -------
    value : float or None
        None if the sensor was not analysed.
    resolved : bool
    """
    if sensor not in noise.get("sensors", {}):
        return None, False
    fits = [a["terms"][term] for a in noise["sensors"][sensor]["axes"].values()]
    values = [f["value"] if f["resolved"] else f["upper_bound"] for f in fits]
    return float(max(values)), all(f["resolved"] for f in fits)
