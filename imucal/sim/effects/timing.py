"""Effects on the packet log and the clocks: packet_loss, timing_jitter, time_offset."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from imucal.sim.effects.base import Effect, RecordingContext, register
from imucal.sim.packets import PacketLog
from imucal.sim.reference import ReferenceClock

LOSS_MODELS = ("bernoulli", "gilbert")


def _gilbert_losses(n: int, fraction: float, burst_mean: float, rng) -> np.ndarray:
    """Loss mask of a two-state (Gilbert) channel: every packet in the bad state is lost.

    Bad runs are geometric with mean ``burst_mean`` packets, good runs geometric with mean
    ``burst_mean (1 - fraction) / fraction``, so the stationary loss fraction is ``fraction``.
    """
    if fraction == 0:
        return np.zeros(n, dtype=bool)
    mean_good = burst_mean * (1 - fraction) / fraction
    bad = rng.random() < fraction
    chunks, total = [], 0
    while total < n:
        m = int(2 * n / (mean_good + burst_mean)) + 8
        good_runs = rng.geometric(1 / mean_good, m)
        bad_runs = rng.geometric(1 / burst_mean, m)
        # a chunk ends in the state opposite to its first, so runs alternate across chunks
        runs = np.column_stack([bad_runs, good_runs] if bad else [good_runs, bad_runs]).ravel()
        chunk = np.repeat(np.tile([bad, not bad], m), runs)
        chunks.append(chunk)
        total += chunk.size
    return np.concatenate(chunks)[:n]


@register
@dataclass(frozen=True)
class PacketLoss(Effect):
    """Radio packets lost between module and receiver (rows dropped, ``seq`` jumps).

    Parameters
    ----------
    fraction : float
        Long-run fraction of lost packets, 0 <= fraction < 1.
    model : str
        'bernoulli' (independent losses) or 'gilbert' (bursts, Gilbert-Elliott channel with a
        lossless good state and an all-loss bad state).
    burst_mean : float
        Mean burst length in packets ('gilbert' only), >= 1.
    """

    name = "packet_loss"
    fraction: float = 0.005
    model: str = "gilbert"
    burst_mean: float = 4.0

    def __post_init__(self) -> None:
        if not 0 <= self.fraction < 1:
            raise ValueError(f"packet_loss fraction must be in [0, 1), got {self.fraction}")
        if self.model not in LOSS_MODELS:
            raise ValueError(f"packet_loss model {self.model!r}; expected one of {LOSS_MODELS}")
        if not self.burst_mean >= 1:
            raise ValueError(f"packet_loss burst_mean must be >= 1 packet, got {self.burst_mean}")
        if self.model == "gilbert" and self.fraction > self.burst_mean / (1 + self.burst_mean):
            raise ValueError(
                f"packet_loss fraction {self.fraction} is too large for burst_mean "
                f"{self.burst_mean}: at most burst_mean / (1 + burst_mean)"
            )

    def on_packets(self, log: PacketLog, ctx: RecordingContext) -> PacketLog:
        rng = ctx.rng(f"effect/{self.name}")
        if self.model == "bernoulli":
            lost = rng.random(len(log)) < self.fraction
        else:
            lost = _gilbert_losses(len(log), self.fraction, self.burst_mean, rng)
        return log.select(~lost)


@register
@dataclass(frozen=True)
class TimingJitter(Effect):
    """Irregular receive timestamps: each packet is stamped after a random delay.

    The delay is exponential with mean (and std) ``std_s``; stamps are then made non-decreasing
    (a packet cannot be logged before the one received earlier), so bursts share stamps.

    Parameters
    ----------
    std_s : float
        Mean and standard deviation of the delay (s), >= 0.
    """

    name = "timing_jitter"
    std_s: float = 0.003

    def __post_init__(self) -> None:
        if not self.std_s >= 0:
            raise ValueError(f"timing_jitter std_s must be >= 0 s, got {self.std_s}")

    def on_packets(self, log: PacketLog, ctx: RecordingContext) -> PacketLog:
        delay = ctx.rng(f"effect/{self.name}").exponential(self.std_s, len(log))
        return log.with_times(np.maximum.accumulate(log.t_s + delay))


@register
@dataclass(frozen=True)
class TimeOffset(Effect):
    """Offset and drift of the reference clock against the module's.

    ``tau = (t_module + offset_s) (1 + drift_ppm 1e-6)``, see :mod:`imucal.sim.reference`.

    Parameters
    ----------
    offset_s : float
        s; positive: the reference started earlier, events appear later on its time axis.
    drift_ppm : float
        Rate error of the reference clock, parts per million.
    """

    name = "time_offset"
    offset_s: float = 0.3
    drift_ppm: float = 0.0

    def on_reference_clock(self, clock: ReferenceClock) -> ReferenceClock:
        return ReferenceClock(offset_s=self.offset_s, drift_ppm=self.drift_ppm)
