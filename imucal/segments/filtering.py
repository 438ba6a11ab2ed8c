"""Zero-phase Butterworth low-pass, applied per contiguous block of a recording.

The paper low-pass filters the accelerometer before its alignment step (Zhang et al. 2014,
Sec. IV-B) but does not say how; the design here is the implementer's choice:

* a Butterworth low-pass of ``order`` and ``cutoff_hz`` in second-order sections, run forwards
  and backwards (``scipy.signal.sosfiltfilt``): zero phase, so edges of motions do not move in
  time, and squared magnitude response ``1 / (1 + (f / f_c)^(2 order))``;
* never across a gap: a recording is split into contiguous blocks wherever the packet counter
  ``seq`` does not step by one (lost packets) or the time step exceeds ``gap_periods`` (5)
  nominal periods with a contiguous counter (the stream stopped, or a multiple of 65536 packets
  was lost). Timestamps are receive times with jitter and bursts (equal stamps), so the counter,
  not a tight time test, is the evidence of loss. Each block is filtered on its own, so data on
  one side of a gap cannot leak to the other side. Within a block the samples are taken as
  uniformly spaced at the nominal period (the median time step; for irregular, bursty
  receive times the effective period, see :mod:`imucal.ingest.timebase`). Without ``seq`` only time
  gaps split;
* a block not longer than the padding ``sosfiltfilt`` needs (``3 (2 n_sections + 1)`` samples,
  15 for order 4, 0.15 s at 100 Hz) is kept unfiltered and reported (logged and listed in
  ``DataFrame.attrs``), never dropped and never filled;
* the magnetometer keeps its own, usually lower, rate: its non-NaN samples are filtered as their
  own series, per block, at the magnetometer's nominal rate when the cutoff is below that rate's
  Nyquist frequency, and left unfiltered (reported) otherwise. NaN rows stay NaN.
"""

from __future__ import annotations

import itertools
import logging

import numpy as np
import pandas as pd
from scipy import signal

from imucal.columns import SENSOR_COLUMNS, SEQ, TIME
from imucal.ingest.timebase import (
    gap_threshold_s,
    nominal_period,
    resolve_packet_steps,
    sampling_period,
)

logger = logging.getLogger(__name__)

#: A time step larger than this many nominal periods splits the recording even when ``seq`` is
#: contiguous; receive-time jitter (bursts) stays well below it.
GAP_PERIODS = 5.0
#: Relative accuracy of a rate derived from timestamps (rounded to 0.1 ms in the raw CSV); a
#: magnetometer whose Nyquist frequency is within this of the cutoff counts as at the cutoff.
RATE_RTOL = 1e-3


def design_lowpass(order: int, cutoff_hz: float, fs_hz: float) -> np.ndarray:
    """Butterworth low-pass in second-order sections.

    Parameters
    ----------
    order : int
        Filter order (>= 1). The zero-phase filter has twice this order in magnitude.
    cutoff_hz : float
        -3 dB frequency of the one-way filter, Hz; must lie in (0, fs_hz / 2).
    fs_hz : float
        Sampling rate, Hz.

    Returns
    -------
    ndarray, shape (n_sections, 6)
        Second-order sections for ``scipy.signal.sosfiltfilt``.

    Raises
    ------
    ValueError
        If the order is not a positive integer or the cutoff is not below the Nyquist frequency.
    """
    if int(order) != order or order < 1:
        raise ValueError(f"filter order {order!r}: expected a positive integer")
    if not np.isfinite(fs_hz) or fs_hz <= 0:
        raise ValueError(f"sampling rate {fs_hz!r} Hz: expected a positive number")
    if not 0 < cutoff_hz < fs_hz / 2:
        raise ValueError(
            f"cutoff {cutoff_hz!r} Hz: expected 0 < cutoff < Nyquist = {fs_hz / 2:g} Hz "
            f"(sampling rate {fs_hz:g} Hz)"
        )
    return signal.butter(int(order), cutoff_hz, btype="lowpass", fs=fs_hz, output="sos")


def padding_length(sos: np.ndarray) -> int:
    """Default padding of ``scipy.signal.sosfiltfilt`` for ``sos``; a block must be longer."""
    n_sections = sos.shape[0]
    zeros = min(int((sos[:, 2] == 0).sum()), int((sos[:, 5] == 0).sum()))
    return 3 * (2 * n_sections + 1 - zeros)


def find_contiguous_blocks(
    t_s: np.ndarray, seq: np.ndarray | None = None, gap_periods: float = GAP_PERIODS
) -> list[tuple[int, int]]:
    """Split a recording into blocks without lost packets or time gaps.

    Parameters
    ----------
    t_s : array_like, shape (n,)
        Timestamps, s, non-decreasing.
    seq : array_like, shape (n,), optional
        Packet counter (16 bit, wraps at 65536). A step other than one packet splits (wraps
        resolved by :func:`imucal.ingest.timebase.resolve_packet_steps`). Without a counter only time
        gaps split, and lost samples within ``gap_periods`` periods cannot be seen.
    gap_periods : float
        A time step longer than :func:`imucal.ingest.timebase.gap_threshold_s` (``gap_periods``
        nominal periods; for irregular timestamps nominal steps include the burst pauses)
        splits.

    Returns
    -------
    list of (int, int)
        ``(start, end)`` row ranges, end exclusive, covering all rows in order.

    Raises
    ------
    ValueError
        If the timestamps do not increase or ``seq`` has another length.
    """
    t = np.asarray(t_s, dtype=float)
    if t.size == 0:
        return []
    if t.size == 1:
        return [(0, 1)]
    cut = np.diff(t) > gap_threshold_s(t, gap_periods)
    if seq is not None:
        s = np.asarray(seq, dtype=np.int64)
        if s.shape != t.shape:
            raise ValueError(f"{SEQ} has shape {s.shape}; expected {t.shape} like {TIME}")
        cut |= resolve_packet_steps(s, t)[0] != 1
    edges = np.concatenate(([0], np.flatnonzero(cut) + 1, [t.size]))
    return [(int(a), int(b)) for a, b in itertools.pairwise(edges)]


def lowpass_block(x: np.ndarray, sos: np.ndarray) -> np.ndarray:
    """Zero-phase filter one contiguous block ``x``, shape (n, k), along axis 0.

    Raises
    ------
    ValueError
        If the block is not longer than the padding of ``sosfiltfilt`` or holds NaN.
    """
    x = np.asarray(x, dtype=float)
    pad = padding_length(sos)
    if x.shape[0] <= pad:
        raise ValueError(f"block of {x.shape[0]} samples: expected more than {pad} to filter")
    if not np.all(np.isfinite(x)):
        raise ValueError("block holds NaN or inf values: expected finite samples only")
    return signal.sosfiltfilt(sos, x, axis=0, padlen=pad)


def _lowpass_series(
    t_s: np.ndarray,
    x: np.ndarray,
    blocks: list[tuple[int, int]],
    sos: np.ndarray,
    name: str,
) -> tuple[np.ndarray, list[dict]]:
    """Filter ``x`` block by block; return the result and the blocks left unfiltered."""
    out = x.copy()
    skipped = []
    pad = padding_length(sos)
    for a, b in blocks:
        if b - a > pad:
            out[a:b] = lowpass_block(x[a:b], sos)
        else:
            skipped.append(
                {
                    "series": name,
                    "rows": b - a,
                    "start_s": float(t_s[a]),
                    "end_s": float(t_s[b - 1]),
                }
            )
            logger.warning(
                "%s: block of %d sample(s) at %.3f-%.3f s is not longer than the filter padding "
                "(%d samples); kept unfiltered",
                name,
                b - a,
                t_s[a],
                t_s[b - 1],
                pad,
            )
    return out, skipped


def lowpass_recording(
    table: pd.DataFrame, *, order: int, cutoff_hz: float, gap_periods: float = GAP_PERIODS
) -> pd.DataFrame:
    """Low-pass the accelerometer, gyroscope and magnetometer of an ingested recording.

    Each sensor present is filtered on its own samples (its rows without NaN). A sensor with a
    sample on every row is filtered per contiguous block of the recording (``seq`` jumps when
    there is a counter, time gaps always). A sensor with samples on some rows only (the
    magnetometer of the native CSV; each stream of a declared recording merged on time) is a
    series of its own: its own nominal rate, split at its own time gaps and at the blocks of the
    recording.

    Irregular timestamps (host receive times in bursts, see :mod:`imucal.ingest.timebase`): the
    samples of a block are taken as uniformly spaced at the *effective* period (mean ordinary
    step), not at the median step, which is the spacing within a burst. The filter then acts on
    the sample sequence as if it were uniform; the timestamps are kept as they are.

    Parameters
    ----------
    table : DataFrame
        Ingested recording (docs/data-format.md): ``t_s``, ``seq`` (optional), the columns of
        the sensors present (``acc_*``, ``gyr_*``, ``mag_*``; NaN on rows without a sample of
        that sensor), extra columns.
    order : int
        Butterworth order of the one-way filter.
    cutoff_hz : float
        -3 dB frequency of the one-way filter, Hz (the zero-phase filter is -6 dB there).
    gap_periods : float
        Time steps longer than this many nominal periods split blocks (as do ``seq`` jumps).

    Returns
    -------
    DataFrame
        Same rows, columns and dtypes; the sensors filtered as above. The magnetometer (and any
        sensor on part of the rows) is left unchanged when the cutoff is not below its Nyquist
        frequency, and reported. ``attrs['lowpass']`` describes the filter, the blocks, each
        sensor series and every block or series left unfiltered.

    Raises
    ------
    ValueError
        If ``t_s`` or every sensor column is missing, the timestamps do not increase, the cutoff
        is not below the Nyquist frequency of acc/gyr, or a row has some but not all three
        values of a sensor.
    """
    present = [s for s, cols in SENSOR_COLUMNS.items() if any(c in table.columns for c in cols)]
    missing = [c for s in present for c in SENSOR_COLUMNS[s] if c not in table.columns]
    if TIME not in table.columns or not present or missing:
        raise ValueError(
            f"recording lacks column(s) {missing or [TIME]}; expected t_s and all three columns "
            "of at least one sensor (the ingested layout)"
        )
    t = table[TIME].to_numpy(dtype=float)
    seq = table[SEQ].to_numpy() if SEQ in table.columns else None
    blocks = find_contiguous_blocks(t, seq, gap_periods)
    fs_hz = 1.0 / nominal_period(t)
    out = table.copy()
    unfiltered: list[dict] = []
    series: dict[str, dict] = {}
    for sensor in present:
        cols = list(SENSOR_COLUMNS[sensor])
        x = table[cols].to_numpy(dtype=float)
        finite = np.isfinite(x)
        partial = np.flatnonzero(finite.any(axis=1) & ~finite.all(axis=1))
        full_rows = finite.all(axis=1)
        if partial.size or (sensor != "mag" and not full_rows.any()):
            bad = np.flatnonzero(~full_rows)
            raise ValueError(
                f"{sensor}: {bad.size} row(s) with NaN/inf, first at row {bad[0]} "
                f"(t = {t[bad[0]]:.3f} s); expected finite values on every row, or all three "
                "values NaN on rows without a sample of this sensor"
            )
        rows = np.flatnonzero(full_rows)
        info: dict = {"rows": int(rows.size)}
        if rows.size == t.size:
            sos = design_lowpass(order, cutoff_hz, fs_hz)
            y, skipped = _lowpass_series(t, x, blocks, sos, sensor)
            out[cols] = y
            unfiltered += skipped
            info.update(fs_hz=fs_hz, filtered=True)
        elif rows.size >= 2:
            t_own = t[rows]
            fs_own = 1.0 / nominal_period(t_own)
            info["fs_hz"] = fs_own
            if cutoff_hz < fs_own / 2 * (1 - RATE_RTOL):
                sos_own = design_lowpass(order, cutoff_hz, fs_own)
                # a block of the series ends at a block boundary of the recording or at its
                # own time gap
                block_id = np.searchsorted([b for _, b in blocks], rows, side="right")
                cut = (np.diff(t_own) > gap_threshold_s(t_own, gap_periods)) | (
                    np.diff(block_id) != 0
                )
                edges = np.concatenate(([0], np.flatnonzero(cut) + 1, [rows.size]))
                own_blocks = [(int(a), int(b)) for a, b in itertools.pairwise(edges)]
                y, skipped = _lowpass_series(t_own, x[rows], own_blocks, sos_own, sensor)
                out.loc[out.index[rows], cols] = y
                unfiltered += skipped
                info["filtered"] = True
            elif sensor != "mag":
                design_lowpass(order, cutoff_hz, fs_own)  # raises: acc/gyr must be filtered
            else:
                info["filtered"] = False
                logger.warning(
                    "%s: cutoff %.3g Hz is not below its Nyquist frequency (%.3g Hz at %.3g Hz); "
                    "kept unfiltered",
                    sensor,
                    cutoff_hz,
                    fs_own / 2,
                    fs_own,
                )
        else:
            info["filtered"] = False
        series[sensor] = info
    out.attrs["lowpass"] = {
        "order": int(order),
        "cutoff_hz": float(cutoff_hz),
        "fs_hz": fs_hz,
        "irregular_timestamps": sampling_period(t)[1],
        "gap_periods": float(gap_periods),
        "blocks": [[a, b] for a, b in blocks],
        "unfiltered": unfiltered,
        "sensors": series,
        "mag": series.get("mag", {"rows": 0, "filtered": False}),
    }
    return out
