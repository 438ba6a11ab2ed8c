"""Time base of a recording: the packet counter across its wraps, and the sampling period.

One place for what ingest, low-pass filtering, segmentation and validation all need:

* :func:`resolve_packet_steps` and :func:`unwrap_counter`: the 16-bit packet counter ``seq``
  wraps at 65536; the receiver time resolves how many wraps a long silence hid.
* :func:`sampling_period`, :func:`nominal_period` and :func:`gap_threshold_s`: the nominal
  period of timestamps that may be *irregular*. Host receive times of a serial or radio link
  come in bursts (sunsided's MPU6050 log: a median step of 2 ms at ~99 Hz, pauses up to 0.5 s
  followed by catch-up bursts). Then the median step says nothing about the rate, and the
  effective period (mean ordinary step) is the nominal period; a time gap is judged against
  the longest ordinary steps, not against the period, since a pause of a few periods is
  buffering, not loss.
"""

from __future__ import annotations

import numpy as np

from imucal.columns import SEQ_MODULUS, TIME

#: Steps up to this long (s) estimate the packet rate that resolves counter wraps in longer
#: ones, and the effective period of irregular timestamps.
ORDINARY_STEP_S = 1.0
#: Timestamps are irregular when the median step is below this fraction of the effective period.
IRREGULAR_RATIO = 0.5
#: Quantile of the ordinary steps that stands for the longest burst pause of irregular timestamps.
PAUSE_QUANTILE = 0.99


def resolve_packet_steps(
    seq: np.ndarray, t_s: np.ndarray, modulus: int = SEQ_MODULUS
) -> tuple[np.ndarray, float]:
    """Number of packets the counter advanced between consecutive rows, wraps resolved.

    Parameters
    ----------
    seq : ndarray, shape (n,)
        Packet counter, integers in ``[0, modulus)``.
    t_s : ndarray, shape (n,)
        Receiver time, s, non-decreasing.
    modulus : int
        The counter wraps at this value.

    Returns
    -------
    advance : ndarray, shape (n - 1,), int64
        Packets from row ``i`` to row ``i + 1``: 1 for consecutive packets, ``k + 1`` after
        ``k`` lost packets, 0 for a repeated counter (duplicated packet), negative for a counter
        that went back (out-of-order packet).
    rate_hz : float
        Packet rate estimated from the ordinary steps (forward by less than half the modulus,
        at most :data:`ORDINARY_STEP_S` long); NaN if the time does not advance in them.

    Notes
    -----
    The counter only gives the advance modulo ``modulus``: ``d = (seq[i+1] - seq[i]) mod M``.
    Of all ``d + k M`` (``k`` integer) the advance is the one nearest to the number of packets
    the elapsed time predicts, ``(t[i+1] - t[i]) * rate_hz``. In a step shorter than
    ``M / (2 rate)`` (327 s at 100 Hz) that is ``d`` or ``d - M``; only a longer silence can
    hide whole wraps, and the time counts them.
    """
    seq = np.asarray(seq, dtype=np.int64)
    t_s = np.asarray(t_s, dtype=float)
    d = np.mod(np.diff(seq), modulus)
    dt = np.diff(t_s)
    ordinary = ordinary_steps(d, dt, modulus)
    elapsed = dt[ordinary].sum()
    rate_hz = float(d[ordinary].sum() / elapsed) if elapsed > 0 else float("nan")
    # Only a step that went back or lasted long can differ from d (cheap on long logs).
    advance = d.copy()
    odd = np.flatnonzero(~ordinary)
    advance[odd] = resolve_odd_steps(d[odd], dt[odd], rate_hz, modulus)
    return advance, rate_hz


def ordinary_steps(d: np.ndarray, dt: np.ndarray, modulus: int = SEQ_MODULUS) -> np.ndarray:
    """Steps whose advance is the counter difference itself (mask, shape (m,)).

    Parameters
    ----------
    d : ndarray of int64, shape (m,)
        Counter differences modulo ``modulus``, ``(seq[i+1] - seq[i]) mod modulus``.
    dt : ndarray, shape (m,)
        Time steps, s.
    modulus : int
        The counter wraps at this value.

    Returns
    -------
    ndarray of bool, shape (m,)
        Forward by less than half the modulus in at most :data:`ORDINARY_STEP_S`. Such a step
        keeps ``d`` for any packet rate below ``modulus / 2 / ORDINARY_STEP_S`` (32 kHz for
        ``seq``); their packets and time estimate the packet rate (:func:`resolve_packet_steps`).
    """
    return (d >= 1) & (d < modulus // 2) & (dt <= ORDINARY_STEP_S)


def resolve_odd_steps(
    d: np.ndarray, dt: np.ndarray, rate_hz: float, modulus: int = SEQ_MODULUS
) -> np.ndarray:
    """Advance of the steps that are not ordinary: the ``d + k modulus`` nearest to the time.

    Parameters
    ----------
    d : ndarray of int64, shape (m,)
        Counter differences modulo ``modulus``.
    dt : ndarray, shape (m,)
        Their time steps, s.
    rate_hz : float
        Packet rate from the ordinary steps (NaN when unknown: then the elapsed time predicts
        no packet).
    modulus : int
        The counter wraps at this value.

    Returns
    -------
    ndarray of int64, shape (m,)
        Packets advanced (0: a repeated counter; negative: the counter went back).
    """
    expected = dt * rate_hz if np.isfinite(rate_hz) else np.zeros(d.size)
    return d + np.round((expected - d) / modulus).astype(np.int64) * modulus


def unwrap_counter(
    counter: np.ndarray, modulus: int = SEQ_MODULUS, t_s: np.ndarray | None = None
) -> np.ndarray:
    """A wrapping counter continued across its wraps.

    Parameters
    ----------
    counter : array_like of int, shape (n,)
        Counter values in ``[0, modulus)``, in order of reception.
    modulus : int
        The counter wraps at this value (65536 for ``seq``, 2^32 for Xsens ``SampleTimeFine``).
    t_s : array_like, shape (n,), optional
        Receiver time, s. With it, each step is :func:`resolve_packet_steps` (a silence may hide
        whole wraps); without it, a step of half the modulus or more counts as going back.

    Returns
    -------
    ndarray of int64, shape (n,)
        ``counter[0]`` plus the cumulative advance.
    """
    c = np.asarray(counter, dtype=np.int64)
    if c.size == 0:
        return c
    if t_s is not None:
        steps, _ = resolve_packet_steps(c, t_s, modulus)
    else:
        steps = np.mod(np.diff(c), modulus)
        steps = np.where(steps >= modulus // 2, steps - modulus, steps)
    return c[0] + np.concatenate(([0], np.cumsum(steps)))


def unwrap_seq(
    seq: np.ndarray, modulus: int = SEQ_MODULUS, t_s: np.ndarray | None = None
) -> np.ndarray:
    """Packet index from a wrapping packet counter, checked (see :func:`unwrap_counter`).

    Parameters
    ----------
    seq : array_like of int, shape (n,)
        Received packet counters in order of reception, counting modulo ``modulus``.
    modulus : int
        Counter period (65536 for a 16-bit counter).
    t_s : array_like, shape (n,), optional
        Receiver times, s; with them a silence longer than a wrap is counted from the time.

    Returns
    -------
    ndarray of int64, shape (n,)
        Index of each packet counted from the first received one (0); lost packets leave gaps.

    Raises
    ------
    ValueError
        If ``seq`` is empty, not one-dimensional, or repeats a counter value (difference 0).

    Notes
    -----
    Without ``t_s`` a loss of ``modulus / 2`` or more consecutive packets cannot be told from a
    counter going back.
    """
    s = np.asarray(seq)
    if s.ndim != 1 or s.size == 0:
        raise ValueError(f"seq must be a non-empty 1-D array, got shape {s.shape}")
    step = np.mod(np.diff(s.astype(np.int64)), modulus)
    if np.any(step == 0):
        first = int(np.flatnonzero(step == 0)[0])
        raise ValueError(
            f"seq repeats the value {int(s[first])} at rows {first} and {first + 1}; "
            "expected a strictly advancing packet counter"
        )
    index = unwrap_counter(s, modulus, t_s)
    return index - index[0]


def sampling_period(t_s: np.ndarray) -> tuple[float, bool]:
    """Nominal sampling period of timestamps ``t_s`` and whether they are irregular.

    Parameters
    ----------
    t_s : array_like, shape (n,)
        Timestamps, s, non-decreasing (equal stamps of a burst allowed).

    Returns
    -------
    period_s : float
        The median step for regular timestamps; for irregular ones the effective period, the
        mean of the ordinary steps (at most ``max(ORDINARY_STEP_S, 10 median)``, so that gaps
        between parts or long losses do not count).
    irregular : bool
        The median step is below :data:`IRREGULAR_RATIO` of the mean ordinary step without the
        longest 1 % (bursts; a few gaps in regular timestamps do not count).

    Raises
    ------
    ValueError
        If there are fewer than two samples, a timestamp decreases or the period is 0.
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
    median = float(np.median(step))
    ordinary = step[step <= max(ORDINARY_STEP_S, 10 * median)]
    # the longest 1 % are left out: a few gaps in regular timestamps must not look like bursts
    trimmed = ordinary[ordinary <= np.quantile(ordinary, PAUSE_QUANTILE)] if ordinary.size else []
    irregular = bool(len(trimmed)) and median < IRREGULAR_RATIO * float(np.mean(trimmed))
    period = float(ordinary.mean()) if irregular else median
    if period <= 0:
        raise ValueError(
            f"{TIME}: median time step is 0 over {t.size} samples; expected a sampling period > 0"
        )
    return period, bool(irregular)


def nominal_period(t_s: np.ndarray) -> float:
    """Nominal sampling period of timestamps ``t_s``, shape (n,), in s.

    The median step; for irregular (bursty) timestamps the effective period
    (:func:`sampling_period`). Equal consecutive stamps are allowed.

    Raises
    ------
    ValueError
        If there are fewer than two samples, a timestamp decreases or the median step is 0.
    """
    return sampling_period(t_s)[0]


def gap_threshold_s(t_s: np.ndarray, gap_periods: float) -> float:
    """Longest time step (s) that is not a gap: ``gap_periods`` nominal periods.

    For irregular timestamps (:func:`sampling_period`) the nominal step is the larger of the
    effective period and the :data:`PAUSE_QUANTILE` quantile of the ordinary steps (the burst
    pauses), so that a receive pause followed by a catch-up burst does not split a block.
    """
    period, irregular = sampling_period(t_s)
    if not irregular:
        return gap_periods * period
    step = np.diff(np.asarray(t_s, dtype=float))
    ordinary = step[step <= max(ORDINARY_STEP_S, 10 * float(np.median(step)))]
    return gap_periods * max(period, float(np.quantile(ordinary, PAUSE_QUANTILE)))


def describe_timestamps(t_s: np.ndarray) -> dict:
    """Statistics of the time steps of ``t_s`` (shape (n,), s) for the ingest summary.

    Returns
    -------
    dict
        ``dt_median_s``, ``dt_mean_s``, ``dt_max_s``, ``effective_rate_hz`` (``n / duration``),
        ``non_increasing_steps`` (steps <= 0: equal stamps of a burst), ``irregular`` (see
        :func:`sampling_period`) and ``nominal_period_s``. Unknown values are None.
    """
    t = np.asarray(t_s, dtype=float)
    if t.size < 2:
        return {k: None for k in ("dt_median_s", "dt_mean_s", "dt_max_s", "effective_rate_hz",
                                  "non_increasing_steps", "irregular", "nominal_period_s")}  # fmt: skip
    step = np.diff(t)
    duration = float(t[-1] - t[0])
    try:
        period, irregular = sampling_period(t)
    except ValueError:
        period, irregular = None, None
    return {
        "dt_median_s": float(np.median(step)),
        "dt_mean_s": float(step.mean()),
        "dt_max_s": float(step.max()),
        "effective_rate_hz": t.size / duration if duration > 0 else None,
        "non_increasing_steps": int(np.count_nonzero(step <= 0)),
        "irregular": irregular,
        "nominal_period_s": period,
    }
