"""Checks of a raw log's content, carried over batches: time and packet order, count range.

A long log is read in batches (:class:`imucal.io.ImuCsvStream`); each check here keeps what it
needs of the rows seen so far (the last time and counter, sums, the first offending row) and
raises at :meth:`~LogChecks.finish` exactly the error it would raise on the whole table, with
the same line, whatever the batch boundaries. :func:`check_log` and :func:`check_count_range`
run them on a table held in memory.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc

from imucal import io
from imucal.columns import SENSOR_COLUMNS, SEQ, SEQ_MODULUS, TIME
from imucal.ingest.timebase import ordinary_steps, resolve_odd_steps

__all__ = ["CountRange", "LogChecks", "check_count_range", "check_log"]

_SENSOR_NAMES = {"acc": "accelerometer", "gyr": "gyroscope", "mag": "magnetometer"}


class LogChecks:
    """Time and packet order of a raw log, checked batch by batch (see :func:`check_log`).

    Parameters
    ----------
    source : str or Path
        File name for the messages.
    first_line : int
        Line number of row 0 in ``source`` (row ``i`` is on line ``first_line + i``).

    Notes
    -----
    Between batches it keeps the last ``t_s`` and ``seq``, the first offending row of each
    check, the packets and time of the ordinary counter steps (their sum is the packet rate)
    and the few steps that are not ordinary (gaps over 1 s, repeated or backward counters):
    whether such a step advanced is decided at the end with the packet rate of the whole log
    (:func:`imucal.ingest.timebase.resolve_packet_steps`).
    """

    def __init__(self, source: str | Path, first_line: int) -> None:
        self.source = source
        self.first_line = int(first_line)
        self.rows = 0
        self._t_first = self._t_last = float("nan")
        self._seq_last = 0
        self._nonfinite: tuple[int, float] | None = None
        self._back: tuple[int, float, float] | None = None
        self._seq_range: tuple[int, int] | None = None
        self._packets = 0
        self._elapsed_s = 0.0
        self._odd: list[tuple[np.ndarray, ...]] = []

    @property
    def failed(self) -> bool:
        """A row already breaks the order (raised by :meth:`finish`)."""
        return self._nonfinite is not None or self._back is not None or self._seq_range is not None

    def update(self, t_s: np.ndarray, seq: np.ndarray) -> None:
        """The next rows of the log: ``t_s`` (s) and ``seq``, shape (m,) each."""
        t_s = np.asarray(t_s, dtype=float)
        seq = np.asarray(seq, dtype=np.int64)
        if t_s.size == 0:
            return
        start = self.rows
        if self._nonfinite is None:
            bad = np.flatnonzero(~np.isfinite(t_s))
            if bad.size:
                self._nonfinite = (start + int(bad[0]), float(t_s[bad[0]]))
        if self._seq_range is None:
            bad = np.flatnonzero((seq < 0) | (seq >= SEQ_MODULUS))
            if bad.size:
                self._seq_range = (start + int(bad[0]), int(seq[bad[0]]))
        if start:  # the step from the previous batch's last row
            t_s = np.concatenate(([self._t_last], t_s))
            seq = np.concatenate(([self._seq_last], seq))
        else:
            self._t_first = float(t_s[0])
        row0 = start - 1 if start else 0  # row of t_s[0]
        dt = np.diff(t_s)
        if self._back is None:
            back = np.flatnonzero(dt < 0)
            if back.size:
                i = int(back[0]) + 1
                self._back = (row0 + i, float(t_s[i]), float(t_s[i - 1]))
        d = np.mod(np.diff(seq), SEQ_MODULUS)
        ordinary = ordinary_steps(d, dt)
        self._packets += int(d[ordinary].sum())
        self._elapsed_s += float(dt[ordinary].sum())
        odd = np.flatnonzero(~ordinary)
        if odd.size:
            self._odd.append((row0 + odd + 1, d[odd], dt[odd], seq[odd], seq[odd + 1]))
        self.rows = start + t_s.size - (1 if start else 0)
        self._t_last = float(t_s[-1])
        self._seq_last = int(seq[-1])

    def finish(self) -> None:
        """Raise the first problem of the whole log, in the order of :func:`check_log`."""
        source, line0, n = self.source, self.first_line, self.rows
        if n < 2:
            raise io.RawDataError(source, line0, f"{n} data row", "at least two rows")
        if self._nonfinite is not None:
            row, value = self._nonfinite
            raise io.RawDataError(
                source, line0 + row, f"t_s is {value}", "a finite receiver time in s"
            )
        if self._back is not None:
            row, t, before = self._back
            raise io.RawDataError(
                source,
                line0 + row,
                f"t_s {t!r} s is earlier than {before!r} s on line {line0 + row - 1}",
                "non-decreasing receiver time t_s",
            )
        if self._t_last == self._t_first:
            raise io.RawDataError(
                source,
                None,
                f"t_s stays at {self._t_first!r} s on all {n} rows",
                "a receiver time that advances",
            )
        if self._seq_range is not None:
            row, value = self._seq_range
            raise io.RawDataError(
                source,
                line0 + row,
                f"seq {value}",
                f"a 16-bit packet counter in 0..{SEQ_MODULUS - 1}",
            )
        if not self._odd:
            return
        row, d, dt, before, after = (np.concatenate(a) for a in zip(*self._odd))
        rate_hz = self._packets / self._elapsed_s if self._elapsed_s > 0 else float("nan")
        advance = resolve_odd_steps(d, dt, rate_hz)
        bad = np.flatnonzero(advance <= 0)
        if not bad.size:
            return
        k = int(bad[0])
        line = line0 + int(row[k])
        if advance[k] == 0:
            found = f"seq {after[k]} repeats the seq of line {line - 1} (duplicated packet)"
        else:
            found = f"seq {after[k]} goes back from {before[k]} on line {line - 1} (out-of-order packet)"
        raise io.RawDataError(
            source, line, found, "each packet once, in order (seq increasing modulo 65536)"
        )


def check_log(table: pd.DataFrame, source: str | Path, first_line: int) -> None:
    """Refuse a log whose time or packet order breaks the contract.

    Parameters
    ----------
    table : DataFrame, shape (n, k)
        With ``t_s`` (s) and ``seq`` columns, one row per packet as read from the file.
    source : str or Path
        File name for the messages.
    first_line : int
        Line number of row 0 in ``source`` (row ``i`` is on line ``first_line + i``).

    Raises
    ------
    RawDataError
        Fewer than two rows, ``t_s`` not finite, going backwards or not advancing at all,
        ``seq`` outside ``[0, 65535]``, a duplicated ``seq`` (same counter as the row before)
        or an out-of-order ``seq``. The message names the first offending line.
    """
    checks = LogChecks(source, first_line)
    checks.update(table[TIME].to_numpy(dtype=float), table[SEQ].to_numpy())
    checks.finish()


class CountRange:
    """Raw counts beyond the ADC's declared range, found batch by batch.

    A reading *at* a limit is a clipped (saturated) sample: the ADC outputs it whenever the
    input exceeds its range, it is legitimate and kept (the segmentation and the fits find
    and leave out clipped samples); :attr:`clipped` counts them per sensor. A count *beyond* a
    limit cannot come from that ADC: the declared range is wrong or the logger overflowed. Such
    a log is refused, never kept.

    Parameters
    ----------
    source : str or Path
        File name for the messages.
    limits : mapping
        Sensor (``acc``, ``gyr``, ``mag``) -> ``(lowest, highest)`` count of its ADC, as
        :attr:`imucal.io.dataset.Dataset.count_range` gives them; sensors absent from the
        mapping are not checked.
    first_line : int or None
        Line number of row 0 in ``source``; None when rows are not lines of the file (the
        message then names the 0-based sample).
    """

    def __init__(
        self,
        source: str | Path,
        limits: Mapping[str, tuple[int, int]],
        first_line: int | None,
    ) -> None:
        self.source = source
        self.limits = {s: (int(lo), int(hi)) for s, (lo, hi) in limits.items()}
        self.first_line = first_line
        self.rows = 0
        self._first: tuple[int, str, str, float] | None = None
        self._count = dict.fromkeys(self.limits, 0)
        self._clipped = dict.fromkeys(self.limits, 0)

    @property
    def clipped(self) -> dict[str, int]:
        """Per checked sensor, the rows so far with a reading at a limit of its range on any
        axis (clipped samples)."""
        return dict(self._clipped)

    @property
    def failed(self) -> bool:
        """A count beyond the range was found (raised by :meth:`finish`)."""
        return self._first is not None

    def update(self, columns: Mapping[str, np.ndarray | pa.Array], rows: int) -> None:
        """The next ``rows`` rows: counts by column name (``acc_x`` ...; NaN/null = no sample).

        Columns of a sensor without limits, or absent from ``columns``, are not checked.
        """
        start = self.rows
        self.rows += int(rows)
        for sensor, (lo, hi) in self.limits.items():
            at_limit = np.zeros(int(rows), dtype=bool)
            for name in SENSOR_COLUMNS[sensor]:
                if name not in columns:
                    continue
                values = columns[name]
                if isinstance(values, np.ndarray):
                    values = pa.array(values, from_pandas=True)  # NaN: no sample
                low_high = pc.min_max(values)
                low, high = low_high["min"].as_py(), low_high["max"].as_py()
                if low is not None and (low <= lo or high >= hi):
                    at = pc.or_(pc.equal(values, lo), pc.equal(values, hi))
                    at_limit |= pc.fill_null(at, False).to_numpy(zero_copy_only=False)
                if low is None or (lo <= low and high <= hi):
                    continue
                beyond = pc.fill_null(pc.or_(pc.less(values, lo), pc.greater(values, hi)), False)
                rows_beyond = np.flatnonzero(beyond.to_numpy(zero_copy_only=False))
                self._count[sensor] += int(rows_beyond.size)
                row = start + int(rows_beyond[0])
                if self._first is None or row < self._first[0]:
                    self._first = (row, sensor, name, values[int(rows_beyond[0])].as_py())
            self._clipped[sensor] += int(at_limit.sum())

    def finish(self) -> None:
        """Raise for the first count beyond the range (the count of all of them in the text)."""
        if self._first is None:
            return
        row, sensor, name, value = self._first
        lo, hi = self.limits[sensor]
        value = int(value) if float(value).is_integer() else value
        count = self._count[sensor]
        if self.first_line is None:
            where, line = f"sample {row} (0-based): ", None
        else:
            where, line = "", self.first_line + row
        raise io.RawDataError(
            self.source,
            line,
            f"{where}{name} is {value} counts, beyond the declared range {lo}..{hi} of the "
            f"{_SENSOR_NAMES[sensor]} (range_counts.{sensor} of dataset.yaml; {count} "
            f"{sensor} count(s) beyond it in the file)",
            f"counts within {lo}..{hi}: a reading at a limit is a clipped sample and is kept, "
            "one beyond it cannot come from the ADC (the declared range is wrong or the "
            "logger overflowed)",
        )


def check_count_range(
    counts: pd.DataFrame,
    source: str | Path,
    limits: Mapping[str, tuple[int, int]],
    first_line: int | None,
) -> dict[str, int]:
    """Refuse raw counts beyond the ADC's declared range (see :class:`CountRange`); count
    the samples at it.

    Parameters
    ----------
    counts : DataFrame, shape (n, k)
        Raw counts in columns ``acc_x`` ... ``mag_z`` (NaN where a sensor has no sample).
    source, limits, first_line
        As :class:`CountRange`.

    Returns
    -------
    dict of str to int
        Per sensor of ``limits``, the rows with a reading at a limit on any axis (clipped).

    Raises
    ------
    RawDataError
        Naming the file, the line (or sample) of the first count beyond the range, the range
        and how many counts of that sensor are beyond it.
    """
    checks = CountRange(source, limits, first_line)
    columns = {c: counts[c].to_numpy(dtype=float) for c in counts.columns}
    checks.update(columns, len(counts))
    checks.finish()
    return checks.clipped


def sensor_limits(
    metadata: Iterable[Mapping[str, Any]], range_counts: Mapping[str, float]
) -> dict[str, float]:
    """The range in SI units of the accelerometer and the gyroscope of a session's recordings.

    Parameters
    ----------
    metadata : iterable of mapping
        The ingested recordings' metadata (``sensors`` present, ``sensitivity`` in SI per
        count, ``source_units`` of a declared recording; a native CSV is read in counts).
    range_counts : mapping
        Sensor -> saturation limit of the raw counts (``Dataset.range_counts``).

    Returns
    -------
    dict of str to float
        Sensor -> ``range_counts x sensitivity``: a reading with ``|value| >=`` it is clipped.
        Only where every recording that holds the sensor reads it in raw counts with that one
        range; otherwise the sensor is absent (its range is not known for all of them, and a
        limit taken from one recording would call readings of another clipped).
    """
    ranges: dict[str, set[float]] = {}
    for meta in metadata:
        units = meta.get("source_units")
        sensitivity = meta.get("sensitivity") or {}
        for sensor in ("acc", "gyr"):
            if sensor not in meta.get("sensors", ()):
                continue
            counts = units is None or units.get(sensor) == "counts"
            known = counts and sensor in range_counts and sensor in sensitivity
            limit = float(range_counts[sensor]) * float(sensitivity[sensor]) if known else None
            ranges.setdefault(sensor, set()).add(limit)
    return {s: v.pop() for s, v in ranges.items() if len(v) == 1 and None not in v}
