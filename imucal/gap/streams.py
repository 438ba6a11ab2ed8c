"""A static recording as streams, and the locations of its gap map.

A static recording holds one or two streams (:data:`STREAMS`): the acc/gyro rows and the
magnetometer rows, each in receive order. Its locations are ``static`` stage x sensor x axis x
segment ``static`` x statistic, measured the same way on a recording and on the replicas of its
twin (:class:`imucal.gap.statictwin.StaticTwin`):

* timing per stream (``imu``: acc/gyro rows; ``mag``): the receive latency above the stream's
  lower envelope (``stamp_scatter_s``), the wander of that envelope about the straight clock
  line (``stamp_wander_s``), the fraction of intervals shorter than a quarter period
  (``burst_fraction``, samples delivered back to back) and longer than three periods
  (``long_gap_fraction``);
* noise per sensor axis: Allan deviation at 10 s and at a fifth of the recording as log-ratio to
  the white-noise line, and the linear trend, all on the stream's sample index (the receive
  times are not the sample times);
* temperature channel: slope of block means on the block-mean temperature per sensor axis
  (acc and gyro on the acc/gyro stream; the magnetometer on its own stream, with the channel
  at its rows: its own readings where every row has one, else interpolated by receive time
  from the rows that have one).

Halves A/B are the first and second half of the recording in time.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.ndimage import minimum_filter1d

from imucal.columns import AXES, SENSOR_COLUMNS, TIME, temperature_column
from imucal.gap.locations import allan_deviation

#: Sensor of each stream of a static recording.
STREAMS = {"imu": ("acc", "gyr"), "mag": ("mag",)}
#: Window of the lower envelope of the receive times (s): longer than a latency burst, shorter
#: than the wander of the host clock against the sample clock.
ENVELOPE_S = 10.0
#: Blocks of the static recording for the temperature regression.
TEMPERATURE_BLOCKS = 16


@dataclass(frozen=True)
class Stream:
    """One stream of a static recording: its rows in receive order.

    Attributes
    ----------
    t_s : ndarray, shape (n,)
        Receive times (s).
    values : dict
        Sensor -> ndarray, shape (n, 3), SI.
    temperature_c : ndarray, shape (n,), or None
    """

    t_s: np.ndarray
    values: dict
    temperature_c: np.ndarray | None = None

    @property
    def rate_hz(self) -> float:
        """Effective sample rate ``(n - 1) / duration`` (Hz)."""
        return (len(self.t_s) - 1) / (self.t_s[-1] - self.t_s[0])

    def half(self, half: str | None) -> Stream:
        if half is None:
            return self
        n = len(self.t_s)
        sl = slice(0, n // 2) if half == "A" else slice(n // 2, n)
        temp = None if self.temperature_c is None else self.temperature_c[sl]
        return Stream(self.t_s[sl], {s: v[sl] for s, v in self.values.items()}, temp)


def streams_half(streams: Mapping[str, Stream], half: str | None) -> dict[str, Stream]:
    """Every stream's first (A) or second (B) half in time, or the whole (None)."""
    return {k: s.half(half) for k, s in streams.items()}


def split_streams(table: pd.DataFrame) -> dict[str, Stream]:
    """The acc/gyro and magnetometer streams of an ingested static recording.

    Parameters
    ----------
    table : DataFrame
        Ingested recording (``t_s``, sensor columns with NaN where a row has no sample of that
        sensor, optionally a temperature column).

    Returns
    -------
    dict
        ``'imu'`` and/or ``'mag'`` -> :class:`Stream` (a stream needs at least 100 rows).
    """
    out = {}
    t = table[TIME].to_numpy(dtype=float)
    col = temperature_column(table)
    for name, sensors in STREAMS.items():
        present = [s for s in sensors if all(c in table.columns for c in SENSOR_COLUMNS[s])]
        if not present:
            continue
        x = {s: table[list(SENSOR_COLUMNS[s])].to_numpy(dtype=float) for s in present}
        rows = np.all(np.column_stack([np.isfinite(v) for v in x.values()]), axis=1)
        if rows.sum() < 100:
            continue
        temp = None if col is None else _stream_temperature(t, table[col], rows, name)
        out[name] = Stream(t[rows], {s: v[rows] for s, v in x.items()}, temp)
    return out


def _stream_temperature(
    t: np.ndarray, column: pd.Series, rows: np.ndarray, name: str
) -> np.ndarray | None:
    """The temperature channel at a stream's rows: its own readings where every row has one;
    for the magnetometer's stream (a sensor read beside the acc/gyro packets, whose rows may
    carry no reading) interpolated by receive time from the rows with a reading, within their
    time range. None where neither holds."""
    temp_all = column.to_numpy(dtype=float)
    ok = np.isfinite(temp_all)
    if np.all(ok[rows]):
        return temp_all[rows]
    if name == "imu" or ok.sum() < 2:
        return None
    t_ok = t[ok]
    if t[rows].min() < t_ok.min() or t[rows].max() > t_ok.max():
        return None
    return np.interp(t[rows], t_ok, temp_all[ok])


def receive_latency(t_s: np.ndarray, rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """Split receive times into a latency above the lower envelope and the envelope's wander.

    Parameters
    ----------
    t_s : ndarray, shape (n,)
        Receive times (s) of consecutive samples.
    rate_hz : float
        Effective sample rate.

    Returns
    -------
    latency : ndarray, shape (n,)
        ``r - envelope`` (s, >= 0) with ``r`` the residual about the straight line
        ``t_0 + k / rate`` and ``envelope`` its running minimum over :data:`ENVELOPE_S`.
    wander : ndarray, shape (n,)
        The envelope about its mean (s): the host clock against the sample clock.
    """
    k = np.arange(len(t_s))
    r = t_s - t_s[0] - k / rate_hz
    w = max(int(ENVELOPE_S * rate_hz) | 1, 3)
    env = minimum_filter1d(r, w, mode="nearest")
    return r - env, env - env.mean()


def timing_statistics(stream: Stream, name: str) -> dict:
    """Timing locations of one stream (see the module docstring)."""
    t = stream.t_s
    rate = stream.rate_hz
    latency, wander = receive_latency(t, rate)
    d = np.diff(t) * rate
    key = ("ingest", "clock", name, "static")
    return {
        (*key, "stamp_scatter_s"): float(max(np.sqrt(np.mean(latency**2)), 1e-7)),
        (*key, "stamp_wander_s"): float(max(np.sqrt(np.mean(wander**2)), 1e-7)),
        (*key, "burst_fraction"): float(np.mean(d < 0.25)),
        (*key, "long_gap_fraction"): float(np.mean(d > 3.0)),
    }


def white_std(x: np.ndarray) -> np.ndarray:
    """White-noise std per axis from first differences, shape (3,) (SI)."""
    return np.std(np.diff(x, axis=0), axis=0) / np.sqrt(2)


def noise_statistics(stream: Stream) -> dict:
    """Allan-deviation excess at 10 s and at a fifth of the recording, and the trend."""
    rate = stream.rate_hz
    out = {}
    for s, x in stream.values.items():
        n = len(x)
        tk = np.arange(n) / rate
        white = white_std(x)
        slope = np.polyfit(tk - tk.mean(), x, 1)[0]
        m10 = max(int(round(10 * rate)), 1)
        mlong = max(n // 5, 1)
        ad10, adl = allan_deviation(x, m10), allan_deviation(x, mlong)
        for j, a in enumerate(AXES):
            key = ("noise", s, a, "static")
            out[(*key, "adev_10s_excess")] = float(np.log(ad10[j] / (white[j] / np.sqrt(m10))))
            out[(*key, "adev_long_excess")] = float(np.log(adl[j] / (white[j] / np.sqrt(mlong))))
            out[(*key, "trend_per_s")] = float(slope[j])
    return out


def temperature_slopes(stream: Stream) -> dict[str, np.ndarray]:
    """Slope of block means on block-mean temperature, per sensor (SI/K), each shape (3,).

    Empty when the stream has no temperature channel or it does not change.
    """
    return {s: slope for s, (slope, _) in temperature_slope_fits(stream).items()}


def temperature_blocks(stream: Stream) -> tuple[np.ndarray, dict] | None:
    """Block means of a stream and their mean temperature.

    The stream is cut into :data:`TEMPERATURE_BLOCKS` blocks of equal sample count.

    Returns
    -------
    tuple or None
        ``temp`` (shape (B,), deg C) and sensor -> block means (shape (B, 3), SI); None when
        the stream has no temperature channel or it does not change.
    """
    if stream.temperature_c is None:
        return None
    edges = np.linspace(0, len(stream.t_s), TEMPERATURE_BLOCKS + 1).astype(int)
    blocks = list(zip(edges[:-1], edges[1:]))
    temp = np.array([stream.temperature_c[a:b].mean() for a, b in blocks])
    if not np.ptp(temp) > 0:
        return None
    means = {
        s: np.array([v[a:b].mean(axis=0) for a, b in blocks])
        for s, v in stream.values.items()
        if s in ("acc", "gyr", "mag")
    }
    return temp, means


def temperature_slope_fits(stream: Stream) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Slope of block means on block-mean temperature per sensor, with its standard deviation.

    Per sensor axis, the block means (:func:`temperature_blocks`) are fitted as a line in the
    block-mean temperature by least squares, and the slope's std is that of least squares
    with the residual variance of the fit (``TEMPERATURE_BLOCKS - 2`` degrees of freedom): it
    holds whatever scatters the block means about the line (white noise, a wandering bias, a
    drift the temperature does not explain).

    Parameters
    ----------
    stream : Stream

    Returns
    -------
    dict
        Sensor -> (slope, std), each shape (3,) (SI/K); empty when the stream has no
        temperature channel or it does not change.
    """
    blocks = temperature_blocks(stream)
    if blocks is None:
        return {}
    temp, means = blocks
    x = temp - temp.mean()
    out = {}
    for s, m in means.items():
        centred = m - m.mean(axis=0)
        slope = x @ centred / (x @ x)
        resid = centred - np.outer(x, slope)
        var = np.sum(resid**2, axis=0) / (len(x) - 2)
        out[s] = (slope, np.sqrt(var / (x @ x)))
    return out


def static_statistics(streams: Mapping[str, Stream], half: str | None = None) -> dict:
    """Every location of a static recording (see the module docstring).

    Parameters
    ----------
    streams : dict
        Output of :func:`split_streams` (or of a twin replica).
    half : {None, 'A', 'B'}
        The whole recording, or its first / second half in time.

    Returns
    -------
    dict
        ``(stage, sensor, axis, segment, statistic)`` -> value (units in the catalogue).
    """
    out = {}
    for name, stream in streams.items():
        s = stream.half(half)
        out.update(timing_statistics(s, name))
        out.update(noise_statistics(s))
        for sensor, slope in temperature_slopes(s).items():
            for j, a in enumerate(AXES):
                out[("temperature", sensor, a, "static", "temp_slope")] = float(slope[j])
    return out
