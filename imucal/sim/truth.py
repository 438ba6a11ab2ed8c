"""The known truth behind a simulated session: sensor errors, world, noise, reference mounting.

Presets
-------
``paper``
    Gyroscope bias and scale from Zhang et al. (2014), Table I and Table II "with tools"; the other
    parameters are fixed plausible values (accelerometer scale within 3 %, bias 0.1-0.3 m/s^2,
    non-orthogonality and misalignment up to about 2 deg; magnetometer scale within 5 %).
``random``
    Drawn from the seed in the same realistic ranges (Monte-Carlo benchmarks).
``demo``
    The ``paper`` truth; the demo's packet loss and reference clock offset are effects
    (see :mod:`imucal.sim.effects`), not part of the truth.
``mems``
    The ``random`` preset with the turn-on biases of a harsh consumer part (MPU-6050 class):
    gyroscope up to +-20 deg/s per axis, accelerometer up to +-0.6 m/s^2 (about 60 mg).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from imucal import errormodel
from imucal.calibration import ImuCalibration, SensorCalibration
from imucal.columns import SENSORS, SI_UNITS

PRESETS = ("paper", "random", "demo", "mems")

#: White-noise standard deviation of the module's readings (SI, per axis), estimated from the
#: static recording of the conformance session: about 8.3 counts acc, 5.6 counts gyr, 4.0 counts
#: mag with the default sensitivities.
MODULE_NOISE = {"acc": 0.020, "gyr": 0.0015, "mag": 0.004}
#: White-noise standard deviation of the Xsens reference (SI), from the conformance export.
REFERENCE_NOISE = {"acc": 0.010, "gyr": 0.0008, "mag": 0.0015}

#: Zhang et al. (2014), Table I (gyroscope bias with tools, rad/s) and Table II (scale with tools).
PAPER_GYR_BIAS = (0.0027, 0.1605, 0.0660)
PAPER_GYR_SCALE = (1.1526, 1.1327, 1.1425)

_PAPER = {
    "acc": {
        "bias": (0.152, -0.218, 0.276),
        "scale": (1.021, 0.982, 1.012),
        "xi_rad": (0.0121, -0.0084, 0.0152),
        "alpha_rad": (-0.0103, 0.0171, 0.0062),
    },
    "gyr": {
        "bias": PAPER_GYR_BIAS,
        "scale": PAPER_GYR_SCALE,
        "xi_rad": (0.0061, -0.0113, 0.0094),
        "alpha_rad": (0.0142, -0.0091, 0.0213),
    },
    "mag": {
        "bias": (0.183, -0.121, 0.254),
        "scale": (1.042, 0.963, 1.018),
        "xi_rad": (0.0213, -0.0152, 0.0281),
        "alpha_rad": (-0.0184, 0.0113, 0.0262),
    },
}
_PAPER_MOUNTING_ROTVEC = (0.0140, -0.0244, 0.0332)  # 2.5 deg

#: Ranges of the ``random`` preset: (low, high) of |bias| and of the scale, max |angle| (rad).
#: The gyroscope scale stays >= 0.95 so that 400 deg/s plus bias fits the int16 range.
_RANDOM_RANGES = {
    "acc": {"bias": (0.05, 0.3), "scale": (0.97, 1.03), "angle": 0.035},
    "gyr": {"bias": (0.0, 0.2), "scale": (0.95, 1.2), "angle": 0.035},
    "mag": {"bias": (0.05, 0.3), "scale": (0.95, 1.05), "angle": 0.035},
}
#: Ranges of the ``mems`` preset: the ``random`` ranges with a consumer part's turn-on biases
#: (MPU-6050 datasheet: gyro initial zero-rate output +-20 deg/s; accelerometer zero-g offset
#: +-50 mg x/y, +-80 mg z). With the default gyro sensitivity (int16 = 500 deg/s), 400 deg/s at
#: the smallest scale 0.95, a 2-deg non-orthogonality and a 20 deg/s bias read at most about
#: 445 deg/s, inside the int16 range (``tests/test_sim.py`` checks the bound).
_MEMS_RANGES = {
    **_RANDOM_RANGES,
    "acc": {**_RANDOM_RANGES["acc"], "bias": (0.05, 0.6)},
    "gyr": {**_RANDOM_RANGES["gyr"], "bias": (0.0, np.radians(20.0))},
}
_RANGES = {"random": _RANDOM_RANGES, "mems": _MEMS_RANGES}


@dataclass(frozen=True)
class World:
    """Gravity and the Earth's magnetic field in the world frame (x magnetic north, z up).

    Attributes
    ----------
    gravity_m_s2 : float
        Local gravity (m/s^2); gravity points along world -z, so a resting accelerometer reads
        specific force ``(0, 0, +g)`` in world axes.
    dip_rad : float
        Magnetic inclination (rad, positive: the field points below the horizon).
    """

    gravity_m_s2: float = 9.81
    dip_rad: float = float(np.radians(64.0))

    @property
    def specific_force(self) -> np.ndarray:
        """Specific force of a body at rest, world axes (m/s^2), shape (3,)."""
        return np.array([0.0, 0.0, self.gravity_m_s2])

    @property
    def field(self) -> np.ndarray:
        """Unit magnetic field vector, world axes, shape (3,)."""
        return np.array([np.cos(self.dip_rad), 0.0, -np.sin(self.dip_rad)])


@dataclass(frozen=True)
class Truth:
    """Everything the simulator renders a session from, apart from the protocol and effects.

    Attributes
    ----------
    calibration : ImuCalibration
        True bias and matrix of each sensor (``calibrated = matrix @ (reading - bias)``).
    world : World
    noise : dict
        White-noise std of the module's readings per sensor (SI, before calibration).
    reference_noise : dict
        White-noise std of the reference's readings per sensor (SI).
    mounting_rotvec_rad : ndarray, shape (3,)
        Rotation vector of the rotation from the reference's axes to B:
        ``v_B = Rot(mounting) v_ref``.
    preset : str
    """

    calibration: ImuCalibration
    world: World
    noise: dict
    reference_noise: dict
    mounting_rotvec_rad: np.ndarray
    preset: str

    @property
    def mounting(self) -> Rotation:
        return Rotation.from_rotvec(self.mounting_rotvec_rad)


def _sensor(sensor: str, bias, scale, xi_rad, alpha_rad, method: str) -> SensorCalibration:
    matrix = errormodel.compose(scale, xi_rad, alpha_rad)
    return SensorCalibration(
        sensor, np.asarray(bias, float), matrix, SI_UNITS[sensor], method=method
    )


def _random_sensor(sensor: str, rng: np.random.Generator, preset: str) -> SensorCalibration:
    r = _RANGES[preset][sensor]
    bias = rng.uniform(*r["bias"], 3) * rng.choice([-1.0, 1.0], 3)
    scale = rng.uniform(*r["scale"], 3)
    xi = rng.uniform(-r["angle"], r["angle"], 3)
    alpha = rng.uniform(-r["angle"], r["angle"], 3)
    return _sensor(sensor, bias, scale, xi, alpha, f"simulated truth ({preset} preset)")


def make_truth(
    preset: str,
    rng: np.random.Generator,
    noise: dict | None = None,
    world: World | None = None,
) -> Truth:
    """Build the truth of a preset.

    Parameters
    ----------
    preset : str
        'paper', 'random', 'demo' or 'mems' (see the module docstring).
    rng : numpy.random.Generator
        Used by the 'random' and 'mems' presets only.
    noise : dict, optional
        Module white-noise std per sensor (SI); default :data:`MODULE_NOISE`.
    world : World, optional
        Default: g = 9.81 m/s^2, dip 64 deg (Freiburg).

    Returns
    -------
    Truth

    Raises
    ------
    ValueError
        For an unknown preset or a negative or missing noise level.
    """
    if preset not in PRESETS:
        raise ValueError(f"unknown preset {preset!r}; expected one of {PRESETS}")
    noise = dict(MODULE_NOISE if noise is None else noise)
    if sorted(noise) != sorted(SENSORS) or any(not v >= 0 for v in noise.values()):
        raise ValueError(f"noise must give a std >= 0 for each of {SENSORS}, got {noise}")
    if preset in _RANGES:
        sensors = [_random_sensor(s, rng, preset) for s in SENSORS]
        angle = rng.uniform(np.radians(1.0), np.radians(3.0))
        axis = rng.normal(size=3)
        mounting = axis / np.linalg.norm(axis) * angle
    else:
        sensors = [
            _sensor(s, **_PAPER[s], method="simulated truth (paper preset)") for s in SENSORS
        ]
        mounting = np.array(_PAPER_MOUNTING_ROTVEC)
    return Truth(
        calibration=ImuCalibration(*sensors),
        world=World() if world is None else world,
        noise=noise,
        reference_noise=dict(REFERENCE_NOISE),
        mounting_rotvec_rad=np.asarray(mounting, dtype=float),
        preset=preset,
    )
