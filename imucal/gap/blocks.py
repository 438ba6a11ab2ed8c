"""A long static recording in bounded size: its full-rate head and the block means of the whole.

The full-protocol diagnosis reads a session's ``static`` recording for two kinds of statistic:
those of single samples (white noise from first differences, the Allan deviation at 10 s, the
receive timestamps, the packet counter, clipping; the gyroscope bias and the twin's noise
level), whose value does not depend on the recording's length, and those of its long time
scales (the Allan deviation at a fifth of the recording, the linear trend, the means of its
eight resting blocks), which need the whole recording but only its means over seconds.

A recording longer than :data:`STATIC_WINDOW_S` is therefore cut into its **window** (the rows
of its first :data:`STATIC_WINDOW_S`, at full rate: the pipeline, the segmentation and the
sample statistics see only these) and its **blocks** (:class:`StaticBlocks`: the means of
consecutive runs of ``samples_per_block`` rows over the whole recording, at most
:data:`STATIC_BLOCKS` of them). A twin replica renders the same two parts
(:func:`imucal.gap.twin.render_static_blocks` draws the blocks at the block rate), so the
diagnosis of a 24 h static recording costs about what a recording of ``STATIC_WINDOW_S`` does.
A recording no longer than the window is used whole, as one block per row
(:func:`long_series`), and its statistics are those of the full-rate definition.

:func:`decimate_static` makes both parts in one pass over row batches, so that a recording read
from its parquet file batch by batch (:func:`read_decimated_static`) is never held whole.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from imucal.columns import SENSOR_COLUMNS, SENSORS, TEMPERATURE_COLUMNS, TIME
from imucal.io.store import read_recording_batches

#: Length (s) of the full-rate head of a long static recording: 30 clusters of the 10 s Allan
#: deviation; a recording no longer than this is used whole.
STATIC_WINDOW_S = 300.0
#: Largest number of block means of a long static recording (the block length follows:
#: 8.6 s at 100 Hz for 24 h, far below the time scales the block statistics look at).
STATIC_BLOCKS = 10_000
#: Column of the number of samples of each sensor in a block (the magnetometer's are fewer).
COUNT_COLUMNS = {s: f"n_{s}" for s in SENSORS}


@dataclass(frozen=True)
class StaticBlocks:
    """Block means of a whole static recording.

    Attributes
    ----------
    table : DataFrame, shape (k, ...)
        Per block: ``t_s`` (mean receive time, s), the sensor columns (NaN-aware means, SI),
        the temperature column when the recording has one, and :data:`COUNT_COLUMNS` (samples
        of each sensor in the block).
    samples_per_block : int
        Rows of the recording per block (the last block may hold fewer).
    start_s : float
        ``t_s`` of the recording's first row.
    n_rows : int
        Rows of the whole recording.
    """

    table: pd.DataFrame
    samples_per_block: int
    start_s: float
    n_rows: int

    def samples(self, sensor: str) -> float:
        """Mean number of samples of ``sensor`` in a block that has one (the statistics leave
        the others out)."""
        counts = self.table[COUNT_COLUMNS[sensor]].to_numpy()
        return float(np.mean(counts[counts > 0]))


def block_rows(n_rows: int) -> int:
    """Rows of a block for a recording of ``n_rows`` rows (at most :data:`STATIC_BLOCKS`)."""
    return max(math.ceil(n_rows / STATIC_BLOCKS), 1)


def _value_columns(columns) -> list[str]:
    cols = [TIME] + [c for s in SENSORS for c in SENSOR_COLUMNS[s] if c in columns]
    return cols + [c for c in TEMPERATURE_COLUMNS if c in columns][:1]


def _block_means(values: np.ndarray, cols: list[str], size: int) -> dict[str, np.ndarray]:
    """Means of consecutive runs of ``size`` rows (the last run may be shorter)."""
    n = len(values)
    k = math.ceil(n / size)
    padded = np.full((k * size, values.shape[1]), np.nan)
    padded[:n] = values
    blocks = padded.reshape(k, size, -1)
    finite = np.isfinite(blocks)
    counts = finite.sum(axis=1)
    sums = np.where(finite, blocks, 0.0).sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        means = sums / counts
    out = {c: means[:, j] for j, c in enumerate(cols)}
    for s in SENSORS:
        if SENSOR_COLUMNS[s][0] in cols:
            j = cols.index(SENSOR_COLUMNS[s][0])
            out[COUNT_COLUMNS[s]] = counts[:, j]
    return out


def decimate_static(
    batches: Iterable[pd.DataFrame], n_rows: int
) -> tuple[pd.DataFrame, StaticBlocks | None]:
    """The window and the blocks of a static recording, in one pass over its rows.

    Parameters
    ----------
    batches : iterable of DataFrame
        The ingested recording's rows in order, in batches of any length.
    n_rows : int
        Rows of the whole recording (fixes the block length, :func:`block_rows`).

    Returns
    -------
    window : DataFrame
        The rows of the first :data:`STATIC_WINDOW_S` (the whole recording when it is no
        longer), every column, a fresh index.
    blocks : StaticBlocks or None
        None when the recording is no longer than the window.

    Raises
    ------
    ValueError
        If the batches hold no row or not ``n_rows`` rows.
    """
    size = block_rows(n_rows)
    window, pending, parts = [], None, []
    t0 = cols = None
    seen = 0
    longer = False
    for batch in batches:
        if not len(batch):
            continue
        if t0 is None:
            t0 = float(batch[TIME].iloc[0])
            cols = _value_columns(batch.columns)
        seen += len(batch)
        t = batch[TIME].to_numpy(dtype=float)
        inside = int(np.searchsorted(t, t0 + STATIC_WINDOW_S, side="right"))
        if inside:
            window.append(batch.iloc[:inside])
        longer |= inside < len(batch)
        values = batch[cols].to_numpy(dtype=float)
        if pending is not None:
            values = np.vstack([pending, values])
        full = len(values) // size * size
        if full:
            parts.append(_block_means(values[:full], cols, size))
        pending = values[full:]
    if t0 is None:
        raise ValueError("the static recording has no row")
    if seen != n_rows:
        raise ValueError(f"the static recording has {seen} rows; expected n_rows = {n_rows}")
    table = pd.concat(window, ignore_index=True)
    if not longer:
        return table, None
    if pending is not None and len(pending):
        parts.append(_block_means(pending, cols, size))
    means = pd.DataFrame({k: np.concatenate([p[k] for p in parts]) for k in parts[0]})
    return table, StaticBlocks(means, size, t0, n_rows)


def decimate_static_table(table: pd.DataFrame) -> tuple[pd.DataFrame, StaticBlocks | None]:
    """:func:`decimate_static` of a recording held in memory (in slices of a block multiple)."""
    step = block_rows(len(table)) * 1000
    return decimate_static(
        (table.iloc[i : i + step] for i in range(0, len(table), step)), len(table)
    )


def read_decimated_static(path: str | Path) -> tuple[pd.DataFrame, StaticBlocks | None]:
    """:func:`decimate_static` of an ingested recording read batch by batch from its file."""
    n_rows, batches = read_recording_batches(path)
    return decimate_static(batches, n_rows)


def window_segments(segments: pd.DataFrame, window: pd.DataFrame) -> pd.DataFrame:
    """The segments table with the static recording's rows cut to its window.

    A segment that starts inside the window ends at the window's end at the latest; one that
    starts after it is dropped (the window's rows are the recording's first).
    """
    n = len(window)
    t = window[TIME].to_numpy(dtype=float)
    static = segments["recording"] == "static"
    keep = ~static | (segments["start_index"] < n)
    out = segments[keep].copy()
    cut = (out["recording"] == "static") & (out["end_index"] > n)
    out.loc[cut, "end_index"] = n
    out.loc[cut, "end_s"] = t[-1]
    out.attrs = dict(segments.attrs)
    return out


def long_series(fit_imu: dict, blocks: StaticBlocks | None) -> tuple[pd.DataFrame, dict, float]:
    """The series the long-time-scale statistics of the static recording are computed on.

    Parameters
    ----------
    fit_imu : dict of str to DataFrame
        A fit's recordings (its ``static`` is the whole recording or its window).
    blocks : StaticBlocks or None

    Returns
    -------
    table : DataFrame
        The block means, or the static recording itself (one block per row).
    samples : dict
        Sensor -> mean number of samples per row of ``table`` (1 for the recording itself).
    start_s : float
        ``t_s`` of the recording's first row.
    """
    if blocks is None:
        table = fit_imu["static"]
        return table, {s: 1.0 for s in SENSORS}, float(table[TIME].iloc[0])
    return blocks.table, {s: blocks.samples(s) for s in SENSORS}, blocks.start_s
