"""Effects on the sensor readings: g_sensitivity, saturation, temperature_drift,
scale_nonlinearity."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from imucal import errormodel
from imucal.columns import SENSORS
from imucal.sim.effects.base import Effect, Magnitude, RecordingContext, axis_values, register
from imucal.sim.motion import KinematicState
from imucal.sim.packets import PacketLog
from imucal.sim.sensors import INT16_MAX, Signals

#: Name of the temperature column added by ``temperature_drift``.
TEMPERATURE_COLUMN = "temp_c"


@register
@dataclass(frozen=True)
class GSensitivity(Effect):
    """Gyroscope output proportional to specific force: ``w_B += G a_B``, a full 3x3 matrix.

    The parameterisation of the model term :class:`imucal.modelterms.GSensitivity`: ``G`` acts
    in frame B (calibrated rate from calibrated specific force), so the raw reading moves by
    ``K^-1 G a_B`` (``K`` the true gyro matrix); the diagonal is the g-sensitivity of each axis
    along its own direction, the off-diagonal elements the cross-axis part.

    Parameters
    ----------
    matrix : tuple, shape (3, 3)
        ``G`` in rad/s per m/s^2, rows the gyro axes and columns the specific force's. One
        number is the same value on the diagonal (0 elsewhere). Realistic: diagonal |G_jj|
        about 0.1-0.2 deg/s/g = 1.8e-4-3.6e-4 (MPU-6050 datasheet 0.1 deg/s/g, ADXRS300
        0.2 deg/s/g; effects.md #4), cross-axis terms a fraction of that, either sign.
    """

    name = "g_sensitivity"
    scalable = ("matrix",)
    matrix: tuple = (
        (2e-4, 5e-5, -3e-5),
        (-4e-5, -1.5e-4, 6e-5),
        (3e-5, -5e-5, 1e-4),
    )

    def __post_init__(self) -> None:
        object.__setattr__(self, "matrix", axis_values(self.name, "matrix", self.matrix, (3, 3)))

    def on_readings(
        self, readings: Signals, true: Signals, state: KinematicState, ctx: RecordingContext
    ) -> Signals:
        cal = ctx.require(self.name, "calibration").sensor("gyr")
        raw = np.linalg.solve(cal.matrix, np.asarray(self.matrix))  # K^-1 G
        return readings.with_sensor("gyr", readings.gyr + true.acc @ raw.T)

    def magnitude(self) -> Magnitude:
        k = float(np.linalg.norm(self.matrix))
        return Magnitude(k, "rad/s per m/s^2", "|G| (Frobenius), gyro output per specific force")


@register
@dataclass(frozen=True)
class Saturation(Effect):
    """Sensors clip at a range smaller than int16 (dataset.yaml gets ``range_counts``).

    Parameters
    ----------
    acc, gyr, mag : int
        Largest |count| each sensor can output, 1..32767. Realistic: the MPU class's default
        ranges, which rate tables often exceed (effects.md #8): with the default sensitivities
        ``acc`` 8191 counts = 2 g and ``gyr`` 16375 counts = 250 deg/s; the magnetometer is
        not clipped.
    """

    name = "saturation"
    priority = 100  # the ADC clips whatever the other sensor effects produced
    acc: int = 8191
    gyr: int = 16375
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

    def scaled(self, factor: float) -> Effect:
        """The gyroscope's range times ``factor`` (rounded to a count); the others kept."""
        if not factor > 0:
            raise ValueError(f"effect {self.name!r}: scale factor must be > 0, got {factor}")
        return dataclasses.replace(self, gyr=round(self.gyr * factor))

    def magnitude(self) -> Magnitude:
        """The gyroscope's clip level (the rate table is where a range is exceeded)."""
        return Magnitude(float(self.gyr), "counts", "largest |count| of the gyroscope")


@register
@dataclass(frozen=True)
class TemperatureDrift(Effect):
    """The module warms up over the session; biases and scales drift per axis; adds ``temp_c``.

    ``T(t) = start_c + rise_c (1 - exp(-t / tau_s))`` on the session clock (recordings follow one
    another, see :func:`imucal.sim.session.simulate_session`), or, where ``path_c`` is given,
    the temperature path it holds: ``T`` interpolated linearly between its values at evenly
    spaced times ``0 .. path_span_s`` (held at its ends outside), a recorded channel that no
    warm-up curve describes (a climate chamber cycled down and up). With ``dT = T - start_c`` and the
    sensor-frame input ``u = matrix^-1 true`` (what the sensing element sees), axis ``j`` of a
    reading becomes ``(1 + s_j dT) u_j + bias_j + b_j dT + noise``; the truth holds at
    ``start_c``. This is the model term's parameterisation
    (:class:`imucal.modelterms.TemperaturePolynomial` at order 1, ``reference_c = start_c``,
    ``bias[0] = b``, ``scale[0] = s``): per axis of the raw reading, either sign.

    Parameters
    ----------
    start_c, rise_c : float
        Temperature at the start of the session and its total rise (deg C). Realistic warm-up:
        a few K over 5-15 min (effects.md #1).
    tau_s : float
        Warm-up time constant (s), > 0 (not read where ``path_c`` is given).
    path_c : tuple of float, optional
        Temperatures (deg C) at ``linspace(0, path_span_s, len(path_c))`` on the session clock,
        at least 2; empty (the default): the warm-up curve.
    path_span_s : float
        Time of the last value of ``path_c`` (s), > 0 where ``path_c`` is given.
    acc_per_k, gyr_per_k, mag_per_k : tuple of 3 float
        Bias drift per kelvin of the x, y, z axes (m/s^2/K, rad/s/K, normalised/K); one number
        is the same drift on all three axes. Realistic: the shape a real part has, each axis
        its own coefficient and sign (effects.md #1a, a CATS tag: gyro -0.001 / +0.026 /
        +0.008 deg/s/K), within the MPU-9250 datasheet's +-1.5 mg/K and +-0.24 deg/s/K
        spreads.
    acc_scale_per_k, gyr_scale_per_k, mag_scale_per_k : tuple of 3 float
        Relative scale drift per kelvin of each axis (1/K). Realistic: acc 0.026 %/K (MPU-9250
        datasheet), gyro about 0.01 %/K of either sign (+-4 % over -40..85 deg C is the worst
        case), magnetometer 0.

    Notes
    -----
    :meth:`magnitude` is the RMS over the axes of the gyro bias drift; :meth:`scaled` multiplies
    every coefficient, keeping the shape across the axes.
    """

    name = "temperature_drift"
    scalable = (
        "acc_per_k", "gyr_per_k", "mag_per_k", "acc_scale_per_k", "gyr_scale_per_k",
        "mag_scale_per_k",
    )  # fmt: skip
    start_c: float = 22.0
    rise_c: float = 8.0
    tau_s: float = 600.0
    acc_per_k: tuple = (0.003, -0.002, 0.004)
    gyr_per_k: tuple = (-1.75e-5, 4.54e-4, 1.4e-4)
    mag_per_k: tuple = (0.0, 0.0, 0.0)
    acc_scale_per_k: tuple = (2.6e-4, 2.6e-4, 2.6e-4)
    gyr_scale_per_k: tuple = (1e-4, -6e-5, 8e-5)
    mag_scale_per_k: tuple = (0.0, 0.0, 0.0)
    path_c: tuple = ()
    path_span_s: float = 0.0

    def __post_init__(self) -> None:
        if not self.tau_s > 0:
            raise ValueError(f"temperature_drift tau_s must be > 0 s, got {self.tau_s}")
        path = tuple(float(v) for v in self.path_c)
        if path and (len(path) < 2 or not np.all(np.isfinite(path)) or not self.path_span_s > 0):
            raise ValueError(
                "temperature_drift path_c needs at least 2 finite temperatures and "
                f"path_span_s > 0 s, got {len(path)} values over {self.path_span_s} s"
            )
        object.__setattr__(self, "path_c", path)
        for key in self.scalable:
            object.__setattr__(self, key, axis_values(self.name, key, getattr(self, key)))

    def coefficients(self, sensor: str) -> tuple[np.ndarray, np.ndarray]:
        """Bias drift (sensor unit/K) and relative scale drift (1/K) of ``sensor``'s axes,
        each shape (3,): the rows ``bias[0]`` and ``scale[0]`` of the model term's polynomial."""
        return (np.array(getattr(self, f"{sensor}_per_k")),
                np.array(getattr(self, f"{sensor}_scale_per_k")))  # fmt: skip

    def temperature_c(self, sample: np.ndarray, ctx: RecordingContext) -> np.ndarray:
        """Temperature (deg C) at module samples ``sample`` of the recording, shape (n,)."""
        t = ctx.session_start_s + np.asarray(sample) / ctx.rate_hz
        if self.path_c:
            knots = np.linspace(0.0, self.path_span_s, len(self.path_c))
            return np.interp(t, knots, self.path_c)
        return self.start_c + self.rise_c * (1 - np.exp(-t / self.tau_s))

    def on_readings(
        self, readings: Signals, true: Signals, state: KinematicState, ctx: RecordingContext
    ) -> Signals:
        dt = self.temperature_c(np.arange(len(true.acc)), ctx) - self.start_c
        out = readings
        for s in SENSORS:
            bias, scale = self.coefficients(s)
            drift = dt[:, None] * bias
            if np.any(scale != 0):
                cal = ctx.require(self.name, "calibration").sensor(s)
                u = errormodel.invert(cal.matrix, np.zeros(3), true.sensor(s))
                drift = drift + dt[:, None] * scale * u
            out = out.with_sensor(s, out.sensor(s) + drift)
        return out

    def on_packets(self, log: PacketLog, ctx: RecordingContext) -> PacketLog:
        return log.with_column(TEMPERATURE_COLUMN, np.round(self.temperature_c(log.sample, ctx), 2))

    def magnitude(self) -> Magnitude:
        rms = float(np.sqrt(np.mean(np.square(self.gyr_per_k))))
        return Magnitude(rms, "rad/s/K", "gyro bias drift per kelvin, RMS over the axes")


@register
@dataclass(frozen=True)
class ScaleNonlinearity(Effect):
    """The sensing element's response is a cubic of its input, relative to the full scale.

    With ``u`` the sensor-frame input (``matrix^-1 true``, SI, the reading without bias and
    noise) and ``FS = 32767 * sensitivity`` the sensor's full scale (SI), every axis reads

    ``u + FS (k2 (u / FS)^2 + k3 (u / FS)^3)``

    so ``k2`` (even: same sign for +-u, an asymmetry) and ``k3`` (odd) are the deviations at
    full scale as fractions of the full scale; the linear term stays the truth's.

    Parameters
    ----------
    acc_k2, acc_k3, gyr_k2, gyr_k3, mag_k2, mag_k3 : float
        Dimensionless. Realistic (MPU-9250 datasheet, effects.md #5): gyro nonlinearity
        0.1 % FS (``gyr_k3`` 1e-3, ``gyr_k2`` 5e-4), accelerometer 0.5 % FS (``acc_k3`` 5e-3,
        ``acc_k2`` 2e-3); magnetometer 0.

    Notes
    -----
    Its signature is a residual of the rate-table plateaus that is curved in the rate (the
    static cube, at +-1 g only, cannot separate ``k2`` from a bias).
    """

    name = "scale_nonlinearity"
    scalable = ("acc_k2", "acc_k3", "gyr_k2", "gyr_k3", "mag_k2", "mag_k3")
    acc_k2: float = 2e-3
    acc_k3: float = 5e-3
    gyr_k2: float = 5e-4
    gyr_k3: float = 1e-3
    mag_k2: float = 0.0
    mag_k3: float = 0.0

    def on_readings(
        self, readings: Signals, true: Signals, state: KinematicState, ctx: RecordingContext
    ) -> Signals:
        out = readings
        for s in SENSORS:
            k2, k3 = getattr(self, f"{s}_k2"), getattr(self, f"{s}_k3")
            if k2 == 0 and k3 == 0:
                continue
            cal = ctx.require(self.name, "calibration").sensor(s)
            full_scale = INT16_MAX * ctx.sensitivity[s]
            x = errormodel.invert(cal.matrix, np.zeros(3), true.sensor(s)) / full_scale
            out = out.with_sensor(s, out.sensor(s) + full_scale * (k2 * x**2 + k3 * x**3))
        return out

    def magnitude(self) -> Magnitude:
        return Magnitude(
            abs(self.gyr_k2) + abs(self.gyr_k3),
            "1",
            "largest gyro deviation at +-full scale, fraction of full scale (|k2| + |k3|)",
        )
