"""Effects on the packet log and the clocks: packet_loss, timing_jitter, time_offset."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from imucal.sim.effects.base import Effect, Magnitude, RecordingContext, register
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
    scalable = ("fraction",)
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

    def magnitude(self) -> Magnitude:
        """Long-run fraction of lost packets (realistic 0.1-5 % in bursts, effects.md #10)."""
        return Magnitude(self.fraction, "1", "long-run fraction of lost packets")


@register
@dataclass(frozen=True)
class TimingJitter(Effect):
    """Irregular receive timestamps: each packet is stamped by the host after a random latency.

    Model: receive time ``t_k = max_{j <= k} (k_j / rate + d_j)`` with the module's sample time
    ``k / rate`` and a non-negative latency ``d_j`` ~ exponential, mean (= std) ``std_s``
    (radio retries, USB/OS scheduling). The receiver logs packets in arrival order, so a packet
    cannot be stamped before one received earlier: a late packet holds back those queued behind
    it and they are stamped together (bursts with equal or near-equal stamps, as in real
    host-receive logs). So ``t_k >= k / rate``, ``t`` is non-decreasing but *not* strictly
    increasing, and ``seq`` stays regular: sample times are recovered from the counter
    (:func:`imucal.validation.packet_times`), never from differences of ``t_s``.

    Parameters
    ----------
    std_s : float
        Mean and standard deviation of the latency (s), >= 0. Realistic: a few ms
        (effects.md #9, "OS/USB/RF timestamp jitter in the ms range").
    """

    name = "timing_jitter"
    scalable = ("std_s",)
    std_s: float = 0.003

    def __post_init__(self) -> None:
        if not self.std_s >= 0:
            raise ValueError(f"timing_jitter std_s must be >= 0 s, got {self.std_s}")

    def on_packets(self, log: PacketLog, ctx: RecordingContext) -> PacketLog:
        delay = ctx.rng(f"effect/{self.name}").exponential(self.std_s, len(log))
        return log.with_times(np.maximum.accumulate(log.t_s + delay))

    def magnitude(self) -> Magnitude:
        return Magnitude(self.std_s, "s", "mean (= std) of the receive latency")


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

    Notes
    -----
    Realistic: up to a few tenths of a second between independently started devices (effects.md
    #10), crystal drift 20-100 ppm. The delay of the magnetometer against acc/gyro inside the
    module is ``mag_latency``'s ``delay_s``.
    """

    name = "time_offset"
    scalable = ("offset_s", "drift_ppm")
    offset_s: float = 0.3
    drift_ppm: float = 0.0

    def on_reference_clock(self, clock: ReferenceClock) -> ReferenceClock:
        return ReferenceClock(offset_s=self.offset_s, drift_ppm=self.drift_ppm)

    def magnitude(self) -> Magnitude:
        return Magnitude(abs(self.offset_s), "s", "|offset| of the reference clock")


@register
@dataclass(frozen=True)
class ReferenceJitter(Effect):
    """The reference's samples are taken at their nominal time stamps plus white jitter.

    Sample ``k`` stamped ``tau_k`` shows the motion at ``tau_k + e_k``, ``e_k ~ N(0, std_s^2)``
    independent: an orientation reference then reads ``q(tau_k) exp(omega e_k)``, an error along
    the rotation axis that grows with the rate, and its rates over an interval ``dt`` carry
    ``omega (e_{k+1} - e_k) / dt``. A camera system's exposure against its time stamps, or a
    reference resampled onto the module's clock, do this.

    Parameters
    ----------
    std_s : float
        s. Realistic: 0.1 ms (an optical reference's frames against the IMU's samples after the
        dataset's synchronisation; far above the cameras' own shutter jitter of microseconds).
    """

    name = "reference_jitter"
    scalable = ("std_s",)
    std_s: float = 1e-4

    def on_reference_times(self, tau_s: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        return tau_s + rng.normal(0.0, self.std_s, np.shape(tau_s))

    def magnitude(self) -> Magnitude:
        return Magnitude(self.std_s, "s", "std of the reference's sampling instants")


@register
@dataclass(frozen=True)
class ClockDrift(Effect):
    """The logger stamps the packets with a clock that runs fast against true time.

    The stamps of a recording are ``t (1 + ppm 1e-6)`` from its first packet, while the module
    samples and the reference runs on true time: against the reference the module's clock
    drifts by ``-ppm`` (the time alignment's ``drift_ppm``). A logger's crystal (20-100 ppm,
    effects.md #9) or a host clock disciplined badly; which of the two clocks is off the data
    cannot tell, only that their rates differ.

    Parameters
    ----------
    ppm : float
        Rate error of the logger's clock against the reference's, parts per million.
        Realistic: 200.
    """

    name = "clock_drift"
    scalable = ("ppm",)
    ppm: float = 200.0

    def on_packets(self, log: PacketLog, ctx: RecordingContext) -> PacketLog:
        t0 = log.t_s[0] if len(log) else 0.0
        return log.with_times(t0 + (log.t_s - t0) * (1 + self.ppm * 1e-6))

    def magnitude(self) -> Magnitude:
        return Magnitude(abs(self.ppm), "ppm", "rate error of the logger's clock")
