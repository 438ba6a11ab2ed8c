"""Outside effects of the sensing element: a scale that depends on the input's sign, a bias that
jumps, a gyroscope output in the square of the specific force, an accelerometer axis that
reads the product of the other two."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from imucal import errormodel
from imucal.sim.effects.base import Effect, Magnitude, RecordingContext, axis_values
from imucal.sim.motion import KinematicState
from imucal.sim.outside.base import register_outside
from imucal.sim.sensors import Signals


class _SignScale(Effect):
    """A sensor whose scale differs for positive and negative inputs, per axis.

    With ``u`` the sensor-frame input (``matrix^-1 true``, SI) each axis reads
    ``u (1 + a sign(u))``, that is ``u + a |u|``: the scale is ``1 + a`` for positive inputs
    and ``1 - a`` for negative ones (their difference ``2 a``). The paper's model has one scale
    per axis; a polynomial in ``u`` (the library's scale non-linearity, even and odd powers)
    does not make a kink at zero.
    """

    sensor = ""
    scalable = ("asymmetry",)

    def __post_init__(self) -> None:
        object.__setattr__(self, "asymmetry", axis_values(self.name, "asymmetry", self.asymmetry))

    def on_readings(
        self, readings: Signals, true: Signals, state: KinematicState, ctx: RecordingContext
    ) -> Signals:
        cal = ctx.require(self.name, "calibration").sensor(self.sensor)
        u = errormodel.invert(cal.matrix, np.zeros(3), true.sensor(self.sensor))
        a = np.asarray(self.asymmetry)
        return readings.with_sensor(self.sensor, readings.sensor(self.sensor) + a * np.abs(u))

    def magnitude(self) -> Magnitude:
        return Magnitude(
            2 * float(np.max(np.abs(self.asymmetry))), "1",
            "largest difference between an axis's scales for positive and negative inputs",
        )  # fmt: skip


@register_outside
@dataclass(frozen=True)
class RateSignScale(_SignScale):
    """The gyroscope's scale differs for positive and negative rates (see :class:`_SignScale`).

    Parameters
    ----------
    asymmetry : tuple of float
        ``a`` per axis, dimensionless. Realistic: 1.5e-3 (0.3 % between the signs), of mixed
        signs; MEMS gyroscopes specify a scale-factor asymmetry of 0.1-1 % (effects.md #5,
        "sign-dependent k+/k-").
    """

    name = "rate_sign_scale"
    sensor = "gyr"
    asymmetry: tuple = (1.5e-3, -1.5e-3, 1.0e-3)


@register_outside
@dataclass(frozen=True)
class AccSignScale(_SignScale):
    """The accelerometer's scale differs for positive and negative specific force (see
    :class:`_SignScale`): at +-1 g alone it is a bias and a scale, at the cube's tilted
    positions it is not.

    Parameters
    ----------
    asymmetry : tuple of float
        ``a`` per axis, dimensionless. Realistic: 2e-3 (0.4 % between the signs; MPU-9250
        accelerometer non-linearity 0.5 %, effects.md #2), of mixed signs.
    """

    name = "acc_sign_scale"
    sensor = "acc"
    asymmetry: tuple = (2e-3, -2e-3, 1.5e-3)


@register_outside
@dataclass(frozen=True)
class BiasStep(Effect):
    """A sensor's bias jumps once, part-way through the session, and stays.

    At session time ``at_s`` (the session clock every recording runs on) the bias of
    ``sensor`` changes by ``step`` (sensor frame, SI) and keeps the new value: a MEMS bias
    shifted by a knock, a supply change, or a mode switch of the part. Neither a wandering
    bias (it is one jump, not a process) nor a drift with temperature.

    Parameters
    ----------
    sensor : str
        'acc', 'gyr' or 'mag'.
    step : tuple of float
        The jump per axis (m/s^2, rad/s or normalised). Realistic: gyro 1.5e-3 rad/s
        (0.09 deg/s) on its largest axis.
    at_s : float
        Session time of the jump (s); the blind protocol's session lasts about 650 s.
    """

    name = "bias_step"
    scalable = ("step",)
    sensor: str = "gyr"
    step: tuple = (1.5e-3, -1.0e-3, 0.5e-3)
    at_s: float = 300.0

    def __post_init__(self) -> None:
        if self.sensor not in ("acc", "gyr", "mag"):
            raise ValueError(f"bias_step sensor must be acc, gyr or mag, got {self.sensor!r}")
        object.__setattr__(self, "step", axis_values(self.name, "step", self.step))

    def on_readings(
        self, readings: Signals, true: Signals, state: KinematicState, ctx: RecordingContext
    ) -> Signals:
        after = (ctx.session_start_s + state.t_s >= self.at_s)[:, None]
        jump = np.asarray(self.step) * after
        return readings.with_sensor(self.sensor, readings.sensor(self.sensor) + jump)

    def magnitude(self) -> Magnitude:
        return Magnitude(float(np.max(np.abs(self.step))), "SI", "largest jump of an axis's bias")


@register_outside
@dataclass(frozen=True)
class G2Sensitivity(Effect):
    """The gyroscope's output follows the square of the specific force along each of its axes.

    ``w += G2 (a_s * a_s)``: with ``a_s`` the specific force in the sensor frame (m/s^2), each
    gyro axis reads ``sum_j G2[i, j] a_s[j]^2`` (rad/s per (m/s^2)^2) on top: a rectification of
    the proof mass's deflection, even in the force. It is not the library's g-sensitivity (linear
    in the force): a pose and its opposite read the same.

    Parameters
    ----------
    matrix : tuple of tuple of float
        ``G2``, 3 x 3, rad/s per (m/s^2)^2. Realistic: a diagonal of 2e-6 (about
        0.01 deg/s/g^2, the g^2 sensitivity MEMS gyroscope datasheets give) with cross terms
        of half that, mixed signs.
    """

    name = "g2_sensitivity"
    scalable = ("matrix",)
    matrix: tuple = ((2e-6, -1e-6, 1e-6), (1e-6, -2e-6, 0.0), (-1e-6, 1e-6, 2e-6))

    def __post_init__(self) -> None:
        object.__setattr__(self, "matrix", axis_values(self.name, "matrix", self.matrix, (3, 3)))

    def on_readings(
        self, readings: Signals, true: Signals, state: KinematicState, ctx: RecordingContext
    ) -> Signals:
        cal = ctx.require(self.name, "calibration").sensor("acc")
        a = errormodel.invert(cal.matrix, np.zeros(3), true.acc)
        return readings.with_sensor("gyr", readings.gyr + (a * a) @ np.asarray(self.matrix).T)

    def magnitude(self) -> Magnitude:
        g = 9.81
        return Magnitude(
            float(np.max(np.abs(np.asarray(self.matrix)))) * g * g, "rad/s",
            "largest gyro output of one axis at 1 g along one axis",
        )  # fmt: skip


@register_outside
@dataclass(frozen=True)
class AccCrossProduct(Effect):
    """Each accelerometer axis reads the product of the other two axes' specific force.

    ``a_i += c_i a_j a_k`` (``(i, j, k)`` cyclic, ``a`` the sensor-frame specific force, m/s^2):
    a second-order cross-axis coupling of the sensing element, zero along one axis and largest
    at the cube's edges and corners. The paper's matrix is the linear cross-axis part.

    Parameters
    ----------
    coupling : tuple of float
        ``c`` per axis, 1/(m/s^2). Realistic: 2e-4 (about 1 mg at an edge, g^2 / 2 c; the MPU
        class's accelerometer non-linearity is 0.5 %, effects.md #2, #6), of mixed signs.
    """

    name = "acc_cross_product"
    scalable = ("coupling",)
    coupling: tuple = (2e-4, -2e-4, 1.5e-4)

    def __post_init__(self) -> None:
        object.__setattr__(self, "coupling", axis_values(self.name, "coupling", self.coupling))

    def on_readings(
        self, readings: Signals, true: Signals, state: KinematicState, ctx: RecordingContext
    ) -> Signals:
        cal = ctx.require(self.name, "calibration").sensor("acc")
        a = errormodel.invert(cal.matrix, np.zeros(3), true.acc)
        product = np.column_stack([a[:, 1] * a[:, 2], a[:, 2] * a[:, 0], a[:, 0] * a[:, 1]])
        return readings.with_sensor("acc", readings.acc + np.asarray(self.coupling) * product)

    def magnitude(self) -> Magnitude:
        return Magnitude(
            float(np.max(np.abs(self.coupling))) * 9.81**2 / 2, "m/s^2",
            "largest reading of one axis at a cube edge (g / sqrt 2 on each of the others)",
        )  # fmt: skip
