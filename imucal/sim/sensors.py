"""From kinematics to raw counts: true signals in B, sensor readings, quantisation.

``true signal (B) --invert error model--> reading (sensor frame, SI) --+ noise--> counts``
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from imucal import errormodel
from imucal.calibration import ImuCalibration
from imucal.columns import SENSORS
from imucal.sim.motion import KinematicState
from imucal.sim.truth import World

#: Range of a signed 16-bit raw count.
INT16_MIN, INT16_MAX = -32768, 32767


@dataclass(frozen=True)
class Signals:
    """The three tri-axial signals at ``n`` samples, each shape (n, 3), SI units.

    ``acc`` specific force (m/s^2), ``gyr`` angular rate (rad/s), ``mag`` normalised field.
    """

    acc: np.ndarray
    gyr: np.ndarray
    mag: np.ndarray

    def sensor(self, name: str) -> np.ndarray:
        if name not in SENSORS:
            raise ValueError(f"unknown sensor {name!r}; expected one of {SENSORS}")
        return getattr(self, name)

    def with_sensor(self, name: str, values: np.ndarray) -> Signals:
        """A copy with one sensor's values replaced."""
        self.sensor(name)
        return replace(self, **{name: values})


def true_signals(state: KinematicState, world: World) -> Signals:
    """Specific force, rate and field in B for a body rotating about a fixed point.

    Parameters
    ----------
    state : KinematicState
        Orientation B -> world and body rate.
    world : World

    Returns
    -------
    Signals
        ``acc = R^T (0, 0, g)``, ``gyr = omega_b``, ``mag = R^T m_world``. Translational
        accelerations are left to effects (e.g. ``lever_arm``).
    """
    rot = state.rotation
    return Signals(
        acc=rot.apply(world.specific_force, inverse=True),
        gyr=state.omega_b.copy(),
        mag=rot.apply(world.field, inverse=True),
    )


def sensor_readings(
    calibration: ImuCalibration, signals: Signals, noise: dict, rng: np.random.Generator
) -> Signals:
    """Readings whose calibration gives ``signals``, plus white noise (eq. 11 inverted).

    Parameters
    ----------
    calibration : ImuCalibration
        The true calibration.
    signals : Signals
        True signals in B.
    noise : dict
        White-noise std (SI) per sensor, added to the reading (sensor frame, before the
        calibration).
    rng : numpy.random.Generator

    Returns
    -------
    Signals
        Readings in SI units in the sensor frame (``counts * sensitivity`` before rounding).
    """
    out = {}
    for s in SENSORS:
        cal = calibration.sensor(s)
        true = signals.sensor(s)
        out[s] = errormodel.invert(cal.matrix, cal.bias, true) + rng.normal(
            0.0, noise[s], true.shape
        )
    return Signals(**out)


def quantise(readings: np.ndarray, sensitivity: float) -> tuple[np.ndarray, int]:
    """Raw counts ``round(reading / sensitivity)`` clipped to the int16 range.

    Parameters
    ----------
    readings : ndarray, shape (n, 3)
        SI units.
    sensitivity : float
        SI unit per count.

    Returns
    -------
    counts : ndarray of int64, shape (n, 3)
    clipped : int
        Number of values that were outside the int16 range.
    """
    raw = np.rint(np.asarray(readings) / sensitivity)
    clipped = int(np.count_nonzero((raw < INT16_MIN) | (raw > INT16_MAX)))
    return np.clip(raw, INT16_MIN, INT16_MAX).astype(np.int64), clipped
