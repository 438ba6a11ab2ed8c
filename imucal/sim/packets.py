"""The packet log of a recording: what the receiver writes to the native raw CSV.

The module samples acc and gyro at 100 Hz and the magnetometer at 10 Hz; every packet carries a
16-bit counter ``seq`` and acc/gyro counts, every 10th packet also a fresh magnetometer sample
(the other rows have empty magnetometer cells). The receiver stamps each packet with its own time
``t_s``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd

from imucal.columns import MAG, RAW_COLUMNS, SENSOR_COLUMNS, SENSORS, SEQ, SEQ_MODULUS, TIME

#: One magnetometer sample per this many packets (10 Hz at 100 Hz).
MAG_EVERY = 10


@dataclass(frozen=True)
class PacketLog:
    """Received packets of one recording, ``n`` rows.

    Attributes
    ----------
    sample : ndarray of int, shape (n,)
        Index ``k`` of the module sample (sampled at ``k / rate_hz`` on the module clock).
    t_s : ndarray, shape (n,)
        Receiver timestamps (s), non-decreasing.
    seq : ndarray of int, shape (n,)
        16-bit packet counter, wraps at 65536.
    counts : dict
        Sensor -> raw counts, int64, shape (n, 3).
    mag_fresh : ndarray of bool, shape (n,)
        Rows that carry a magnetometer sample.
    extra : dict
        Extra column name -> values, shape (n,) (written after the standard columns).
    """

    sample: np.ndarray
    t_s: np.ndarray
    seq: np.ndarray
    counts: dict
    mag_fresh: np.ndarray
    extra: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return int(self.sample.size)

    def select(self, keep: np.ndarray) -> PacketLog:
        """The rows where the boolean mask ``keep`` (shape (n,)) is True."""
        keep = np.asarray(keep, dtype=bool)
        if keep.shape != self.sample.shape:
            raise ValueError(f"mask has shape {keep.shape}, expected {self.sample.shape}")
        return PacketLog(
            self.sample[keep],
            self.t_s[keep],
            self.seq[keep],
            {s: c[keep] for s, c in self.counts.items()},
            self.mag_fresh[keep],
            {k: v[keep] for k, v in self.extra.items()},
        )

    def with_times(self, t_s: np.ndarray) -> PacketLog:
        t = np.asarray(t_s, dtype=float)
        if t.shape != self.t_s.shape or np.any(np.diff(t) < 0):
            raise ValueError("receiver timestamps must keep the row count and be non-decreasing")
        return replace(self, t_s=t)

    def with_column(self, name: str, values: np.ndarray) -> PacketLog:
        """A copy with an extra column (e.g. ``temp_c``)."""
        if name in RAW_COLUMNS:
            raise ValueError(f"extra column {name!r} clashes with a standard column")
        v = np.asarray(values, dtype=float)
        if v.shape != self.sample.shape:
            raise ValueError(f"column {name!r} has shape {v.shape}, expected {self.sample.shape}")
        return replace(self, extra={**self.extra, name: v})


def build_packet_log(
    counts: dict, seq_start: int, rate_hz: float, mag_every: int = MAG_EVERY
) -> PacketLog:
    """The log of a loss-free recording stamped with the module's sample times.

    Parameters
    ----------
    counts : dict
        Sensor -> int counts, shape (n, 3) each.
    seq_start : int
        Counter value of the first packet, 0..65535.
    rate_hz : float
        Packet rate.
    mag_every : int
        A magnetometer sample on packets ``0, mag_every, 2 mag_every, ...``.

    Returns
    -------
    PacketLog
    """
    if not 0 <= seq_start < SEQ_MODULUS:
        raise ValueError(f"seq_start {seq_start} outside 0..{SEQ_MODULUS - 1}")
    n = len(counts["acc"])
    k = np.arange(n)
    return PacketLog(
        sample=k,
        t_s=k / rate_hz,
        seq=(seq_start + k) % SEQ_MODULUS,
        counts={s: np.asarray(counts[s], dtype=np.int64) for s in SENSORS},
        mag_fresh=k % mag_every == 0,
    )


def to_frame(log: PacketLog) -> pd.DataFrame:
    """The raw-CSV table: ``RAW_COLUMNS`` then the extra columns; empty mag cells as <NA>."""
    data: dict = {TIME: log.t_s, SEQ: log.seq}
    for s in SENSORS:
        for j, col in enumerate(SENSOR_COLUMNS[s]):
            values = log.counts[s][:, j]
            if col in MAG:
                data[col] = pd.array(np.where(log.mag_fresh, values, 0), dtype="Int64")
                data[col][~log.mag_fresh] = pd.NA
            else:
                data[col] = values
    data.update(log.extra)
    return pd.DataFrame(data)
