"""Effects on the sensor readings: g_sensitivity, saturation, temperature_drift."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from imucal.columns import SENSORS
from imucal.sim.effects.base import Effect, RecordingContext, register
from imucal.sim.motion import KinematicState
from imucal.sim.packets import PacketLog
from imucal.sim.sensors import INT16_MAX, Signals

#: Name of the temperature column added by ``temperature_drift``.
TEMPERATURE_COLUMN = "temp_c"


@register
@dataclass(frozen=True)
class GSensitivity(Effect):
    """Gyroscope output proportional to specific force: ``gyr += k * acc`` per axis.

    Parameters
    ----------
    kx, ky, kz : float
        rad/s per m/s^2 (typical MEMS: 1e-4 .. 1e-3).
    """

    name = "g_sensitivity"
    kx: float = 2e-4
    ky: float = -1.5e-4
    kz: float = 1e-4

    def on_readings(
        self, readings: Signals, true: Signals, state: KinematicState, ctx: RecordingContext
    ) -> Signals:
        k = np.array([self.kx, self.ky, self.kz])
        return readings.with_sensor("gyr", readings.gyr + true.acc * k)


@register
@dataclass(frozen=True)
class Saturation(Effect):
    """Sensors clip at a range smaller than int16 (dataset.yaml gets ``range_counts``).

    Parameters
    ----------
    acc, gyr, mag : int
        Largest |count| each sensor can output, 1..32767.
    """

    name = "saturation"
    priority = 100  # the ADC clips whatever the other sensor effects produced
    acc: int = 8191
    gyr: int = INT16_MAX
    mag: int = INT16_MAX

    def __post_init__(self) -> None:
        for s in SENSORS:
            if not 1 <= getattr(self, s) <= INT16_MAX:
                raise ValueError(f"saturation {s}={getattr(self, s)} outside 1..{INT16_MAX}")

    def on_readings(
        self, readings: Signals, true: Signals, state: KinematicState, ctx: RecordingContext
    ) -> Signals:
        out = readings
        for s in SENSORS:
            limit = getattr(self, s) * ctx.sensitivity[s]
            out = out.with_sensor(s, np.clip(out.sensor(s), -limit, limit))
        return out

    def dataset_overrides(self) -> dict:
        return {"range_counts": {s: getattr(self, s) for s in SENSORS}}


@register
@dataclass(frozen=True)
class TemperatureDrift(Effect):
    """The module warms up over the session; biases drift with temperature; adds ``temp_c``.

    ``T(t) = start_c + rise_c (1 - exp(-t / tau_s))`` on the session clock (recordings follow one
    another, see :func:`imucal.sim.session.simulate_session`). Each reading shifts by
    ``coefficient * (T - start_c)`` on all three axes; the truth holds at ``start_c``.

    Parameters
    ----------
    start_c, rise_c : float
        Temperature at the start of the session and its total rise (deg C).
    tau_s : float
        Warm-up time constant (s), > 0.
    acc_per_k, gyr_per_k, mag_per_k : float
        Bias drift per kelvin (m/s^2/K, rad/s/K, normalised/K).
    """

    name = "temperature_drift"
    start_c: float = 22.0
    rise_c: float = 8.0
    tau_s: float = 600.0
    acc_per_k: float = 0.003
    gyr_per_k: float = 0.0005
    mag_per_k: float = 0.0

    def __post_init__(self) -> None:
        if not self.tau_s > 0:
            raise ValueError(f"temperature_drift tau_s must be > 0 s, got {self.tau_s}")

    def temperature_c(self, sample: np.ndarray, ctx: RecordingContext) -> np.ndarray:
        """Temperature (deg C) at module samples ``sample`` of the recording, shape (n,)."""
        t = ctx.session_start_s + np.asarray(sample) / ctx.rate_hz
        return self.start_c + self.rise_c * (1 - np.exp(-t / self.tau_s))

    def on_readings(
        self, readings: Signals, true: Signals, state: KinematicState, ctx: RecordingContext
    ) -> Signals:
        dt = self.temperature_c(np.arange(len(true.acc)), ctx) - self.start_c
        out = readings
        for s in SENSORS:
            out = out.with_sensor(s, out.sensor(s) + getattr(self, f"{s}_per_k") * dt[:, None])
        return out

    def on_packets(self, log: PacketLog, ctx: RecordingContext) -> PacketLog:
        return log.with_column(TEMPERATURE_COLUMN, np.round(self.temperature_c(log.sample, ctx), 2))
