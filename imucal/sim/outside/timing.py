"""Outside effects of the module's timing: a digital low-pass filter on its output."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy.signal import butter, lfilter, lfilter_zi

from imucal.sim.effects.base import Effect, Magnitude, RecordingContext
from imucal.sim.motion import KinematicState
from imucal.sim.outside.base import register_outside
from imucal.sim.sensors import Signals


@register_outside
@dataclass(frozen=True)
class OutputFilter(Effect):
    """A causal second-order Butterworth low-pass on the accelerometer and gyroscope outputs,
    noise included (the MPU class's digital low-pass filter, DLPF).

    The output is delayed (group delay ``sqrt(2) / (2 pi cutoff_hz)`` at low frequencies, 11 ms
    at 20 Hz) and its noise is no longer white: the first differences of a static reading
    shrink more than its slow part, so a white-noise level read from them understates the
    noise density (effects.md #17).

    Parameters
    ----------
    cutoff_hz : float
        -3 dB frequency (Hz), below the Nyquist frequency of the packet rate. Realistic: 20 Hz
        (the MPU-9250's DLPF settings 5-184 Hz at 100 Hz output).
    """

    name = "output_filter"
    cutoff_hz: float = 20.0

    def __post_init__(self) -> None:
        if not self.cutoff_hz > 0:
            raise ValueError(f"output_filter cutoff_hz must be > 0, got {self.cutoff_hz}")

    def on_readings(
        self, readings: Signals, true: Signals, state: KinematicState, ctx: RecordingContext
    ) -> Signals:
        nyquist = ctx.rate_hz / 2
        if not self.cutoff_hz < nyquist:
            raise ValueError(
                f"output_filter cutoff {self.cutoff_hz} Hz is not below the Nyquist frequency "
                f"{nyquist} Hz of {ctx.recording}"
            )
        b, a = butter(2, self.cutoff_hz / nyquist)
        zi = lfilter_zi(b, a)
        out = readings
        for s in ("acc", "gyr"):
            x = readings.sensor(s)
            y = np.column_stack([lfilter(b, a, x[:, j], zi=zi * x[0, j])[0] for j in range(3)])
            out = out.with_sensor(s, y)
        return out

    def scaled(self, factor: float) -> Effect:
        """The delay times ``factor``: the cutoff divided by it."""
        if not factor > 0:
            raise ValueError(f"effect {self.name!r}: scale factor must be > 0, got {factor}")
        return dataclasses.replace(self, cutoff_hz=self.cutoff_hz / factor)

    def magnitude(self) -> Magnitude:
        return Magnitude(
            float(np.sqrt(2) / (2 * np.pi * self.cutoff_hz)), "s", "group delay at low frequencies"
        )
