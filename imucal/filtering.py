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
  uniformly spaced at the nominal period (the median time step);
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

from imucal.columns import ACC, GYR, MAG, SEQ, SEQ_MODULUS, TIME

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


def nominal_period(t_s: np.ndarray) -> float:
    """Nominal sampling period (median time step) of timestamps ``t_s``, shape (n,), in s.

    Equal consecutive stamps (packets received in a burst) are allowed.

    Raises
    ------
    ValueError
        If there are fewer than two samples, a timestamp decreases or the median step is 0.
    """
    t = np.asarray(t_s, dtype=float)
    if t.size < 2:
        raise ValueError(f"{t.size} timestamp(s): need at least 2 to find the sampling period")
    step = np.diff(t)
    bad = np.flatnonzero(~(step >= 0))
    if bad.size:
        i = int(bad[0])
        raise ValueError(
            f"{TIME} decreases at row {i + 1}: {t[i]:.6g} s -> {t[i + 1]:.6g} s "
            f"({bad.size} such step(s)); expected non-decreasing timestamps"
        )
    period = float(np.median(step))
    if period <= 0:
        raise ValueError(
            f"{TIME}: median time step is 0 over {t.size} samples; expected a sampling period > 0"
        )
    return period


def find_contiguous_blocks(
    t_s: np.ndarray, seq: np.ndarray | None = None, gap_periods: float = GAP_PERIODS
) -> list[tuple[int, int]]:
    """Split a recording into blocks without lost packets or time gaps.

    Parameters
    ----------
    t_s : array_like, shape (n,)
        Timestamps, s, non-decreasing.
    seq : array_like, shape (n,), optional
        Packet counter (16 bit, wraps at 65536). A step other than +1 splits.
    gap_periods : float
        A time step larger than ``gap_periods`` nominal periods (median step) splits.

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
    period = nominal_period(t)
    cut = np.diff(t) > gap_periods * period
    if seq is not None:
        s = np.asarray(seq, dtype=np.int64)
        if s.shape != t.shape:
            raise ValueError(f"{SEQ} has shape {s.shape}; expected {t.shape} like {TIME}")
        cut |= np.mod(np.diff(s), SEQ_MODULUS) != 1
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

    Parameters
    ----------
    table : DataFrame
        Ingested recording (docs/architecture.md): ``t_s``, ``seq``, ``acc_*``, ``gyr_*``,
        ``mag_*`` (NaN on rows without a fresh magnetometer sample), extra columns.
    order : int
        Butterworth order of the one-way filter.
    cutoff_hz : float
        -3 dB frequency of the one-way filter, Hz (the zero-phase filter is -6 dB there).
    gap_periods : float
        Time steps longer than this many nominal periods split blocks (as do ``seq`` jumps).

    Returns
    -------
    DataFrame
        Same rows, columns and dtypes; ``acc_*``, ``gyr_*`` filtered per contiguous block; the
        non-NaN ``mag_*`` samples filtered per block at their own rate when the cutoff is below
        their Nyquist frequency, else unchanged. ``attrs['lowpass']`` describes the filter, the
        blocks and every block or series left unfiltered.

    Raises
    ------
    ValueError
        If a column is missing, the timestamps do not increase, the cutoff is not below the
        Nyquist frequency of acc/gyr, or acc/gyr hold NaN.
    """
    missing = [c for c in (TIME, SEQ, *ACC, *GYR, *MAG) if c not in table.columns]
    if missing:
        raise ValueError(f"recording lacks column(s) {missing}; expected the ingested layout")
    t = table[TIME].to_numpy(dtype=float)
    blocks = find_contiguous_blocks(t, table[SEQ].to_numpy(), gap_periods)
    fs_hz = 1.0 / nominal_period(t)
    sos = design_lowpass(order, cutoff_hz, fs_hz)
    out = table.copy()
    unfiltered: list[dict] = []
    for cols, name in ((ACC, "acc"), (GYR, "gyr")):
        x = table[list(cols)].to_numpy(dtype=float)
        bad = np.flatnonzero(~np.isfinite(x).all(axis=1))
        if bad.size:
            raise ValueError(
                f"{name}: {bad.size} row(s) with NaN/inf, first at row {bad[0]} "
                f"(t = {t[bad[0]]:.3f} s); expected finite values on every row"
            )
        y, skipped = _lowpass_series(t, x, blocks, sos, name)
        out[list(cols)] = y
        unfiltered += skipped

    mag = table[list(MAG)].to_numpy(dtype=float)
    rows = np.flatnonzero(np.isfinite(mag).all(axis=1))
    mag_info: dict = {"rows": int(rows.size)}
    if rows.size >= 2:
        t_mag = t[rows]
        fs_mag = 1.0 / nominal_period(t_mag)
        mag_info["fs_hz"] = fs_mag
        if cutoff_hz < fs_mag / 2 * (1 - RATE_RTOL):
            sos_mag = design_lowpass(order, cutoff_hz, fs_mag)
            # a magnetometer block ends at a main-stream block boundary or at its own time gap
            block_id = np.searchsorted([b for _, b in blocks], rows, side="right")
            cut = (np.diff(t_mag) > gap_periods / fs_mag) | (np.diff(block_id) != 0)
            edges = np.concatenate(([0], np.flatnonzero(cut) + 1, [rows.size]))
            mag_blocks = [(int(a), int(b)) for a, b in itertools.pairwise(edges)]
            y, skipped = _lowpass_series(t_mag, mag[rows], mag_blocks, sos_mag, "mag")
            out.loc[out.index[rows], list(MAG)] = y
            unfiltered += skipped
            mag_info["filtered"] = True
        else:
            mag_info["filtered"] = False
            logger.warning(
                "mag: cutoff %.3g Hz is not below the magnetometer's Nyquist frequency "
                "(%.3g Hz at %.3g Hz); magnetometer kept unfiltered",
                cutoff_hz,
                fs_mag / 2,
                fs_mag,
            )
    else:
        mag_info["filtered"] = False
    out.attrs["lowpass"] = {
        "order": int(order),
        "cutoff_hz": float(cutoff_hz),
        "fs_hz": fs_hz,
        "gap_periods": float(gap_periods),
        "blocks": [[a, b] for a, b in blocks],
        "unfiltered": unfiltered,
        "mag": mag_info,
    }
    return out
