"""Effects on the true signals in B: lever_arm, earth_rotation."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from imucal.constants import EARTH_RATE_RAD_S
from imucal.sim.effects.base import Effect, Magnitude, RecordingContext, register
from imucal.sim.motion import KinematicState
from imucal.sim.sensors import Signals


@register
@dataclass(frozen=True)
class LeverArm(Effect):
    """The accelerometer sits off the rotation centre: centripetal and tangential acceleration.

    Adds ``omega x (omega x r) + omega_dot x r`` (all in B) to the specific force.

    Parameters
    ----------
    x_m, y_m, z_m : float
        Position ``r`` of the accelerometer relative to the centre of rotation, in B (m).
        Realistic: a few cm on a platform or table (effects.md #14: 5 cm at 360 deg/s gives
        0.2 g).
    """

    name = "lever_arm"
    scalable = ("x_m", "y_m", "z_m")
    x_m: float = 0.03
    y_m: float = 0.02
    z_m: float = 0.0

    def on_true_signals(
        self, signals: Signals, state: KinematicState, ctx: RecordingContext
    ) -> Signals:
        r = np.array([self.x_m, self.y_m, self.z_m])
        w = state.omega_b
        extra = np.cross(w, np.cross(w, r)) + np.cross(state.omega_dot_b, r)
        return signals.with_sensor("acc", signals.acc + extra)

    def magnitude(self) -> Magnitude:
        r = float(np.linalg.norm([self.x_m, self.y_m, self.z_m]))
        return Magnitude(r, "m", "|r|, distance of the accelerometer from the rotation centre")


@register
@dataclass(frozen=True)
class EarthRotation(Effect):
    """The gyroscope senses the Earth's rotation (world x = north, declination neglected).

    Adds ``R^T rate_rad_s (cos lat, 0, sin lat)`` to the true rate in B.

    Parameters
    ----------
    latitude_deg : float
        Geographic latitude (deg); default Freiburg.
    rate_rad_s : float
        The Earth's rotation rate (rad/s), sidereal; change it only to exaggerate the effect
        in a test or a blind check.
    """

    name = "earth_rotation"
    scalable = ("rate_rad_s",)
    latitude_deg: float = 48.0
    rate_rad_s: float = EARTH_RATE_RAD_S

    def on_true_signals(
        self, signals: Signals, state: KinematicState, ctx: RecordingContext
    ) -> Signals:
        lat = np.radians(self.latitude_deg)
        earth_world = self.rate_rad_s * np.array([np.cos(lat), 0.0, np.sin(lat)])
        return signals.with_sensor(
            "gyr", signals.gyr + state.rotation.apply(earth_world, inverse=True)
        )

    def magnitude(self) -> Magnitude:
        return Magnitude(self.rate_rad_s, "rad/s", "rotation rate of the Earth")
