"""Disturbances a hand-held or robot-borne module meets: world_magnetic, shock, vibration.

``world_magnetic`` changes the true field (a field fixed in the world that varies with the
sensor's position); ``shock`` and ``vibration`` add to the readings what the module senses and
an orientation reference does not resolve (a few milliseconds of a knock, a line at tens of Hz).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from imucal.sim.effects.base import Effect, Magnitude, RecordingContext, register
from imucal.sim.motion import KinematicState
from imucal.sim.sensors import Signals


def gradient_matrix(xx: float, yy: float, xy: float, xz: float, yz: float) -> np.ndarray:
    """The symmetric, traceless 3 x 3 gradient of a static field in free space (curl and
    divergence vanish) from its five free entries; ``zz = -(xx + yy)``."""
    return np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, -(xx + yy)]])


def dipole_field(position: np.ndarray, centre: np.ndarray, moment: np.ndarray) -> np.ndarray:
    """The field of a dipole at ``centre`` (m) of ``moment`` (field times m^3) at
    ``position`` (m, shape (n, 3)): ``(3 u (u . k) - k) / d^3``, shape (n, 3)."""
    d = np.asarray(position, dtype=float) - centre
    r = np.linalg.norm(d, axis=1, keepdims=True)
    u = d / r
    return (3.0 * u * (u @ moment)[:, None] - moment) / r**3


def random_unit(rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` directions uniform on the sphere, shape (n, 3)."""
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


@register
@dataclass(frozen=True)
class WorldMagnetic(Effect):
    """A field fixed in the world that changes with where the sensor is (a magnet or steel near
    the path), not with its attitude.

    A hand turns the module about the wrist, a robot about its flange: the sensor sits at
    ``r`` (B, m) from a pivot fixed in the world, so it is at ``p(t) = R(t) r`` (world, from
    the pivot) and its position follows its orientation ``R`` (B -> world). About the path the
    disturbance is taken to first order, a field gradient ``G`` (world axes, Earth fields per
    m; symmetric and traceless, as for any static field in free space):

    ``m_B = R^T (m_earth + G R r)``

    The constant part (``G`` times the pivot's offset) only changes the apparent Earth field
    and is left out. The world field a reference's orientation carries the readings into,
    ``R m_B``, is then not constant but linear in the entries of ``R``: it follows the
    trajectory, not the rate (as a magnetometer lag would) and not the reference's own noise.

    Parameters
    ----------
    arm_x_m, arm_y_m, arm_z_m : float
        ``r``, the sensor from the pivot in B, m. Realistic: 0.15 m (a hand's module).
    grad_xx, grad_yy, grad_xy, grad_xz, grad_yz : float
        The free entries of ``G`` (:func:`gradient_matrix`), Earth fields per m. Realistic
        ``|G|`` (Frobenius) 0.53 per m, about 25 uT/m: a small NdFeB disc (10 x 3 mm, moment
        about 0.24 A m^2) 0.3 m from the path gives 1.8 uT and 18 uT/m (dipole, ``3 B / d``);
        steel furniture or a robot's base a similar few uT over tens of cm **[computed]**.

    dipole_x_m, dipole_y_m, dipole_z_m : float
        Where a magnetic dipole sits in the world, m (read only with a position track).
    moment_x, moment_y, moment_z : float
        Its moment in Earth fields times m^3 (``mu_0 m / (4 pi |B_earth|)``): a field
        ``(3 u (u . k) - k) / d^3`` at distance ``d`` along ``u``. Default 0 (no dipole);
        a small NdFeB disc of 0.24 A m^2 is 5.5e-4 against 44 uT.

    Notes
    -----
    Magnitude ``|G| |r|``: the size of the position-dependent field over the arm (Earth
    fields; realistic 0.08, about 4 uT). Only the product ``G r`` is observable from the
    orientation: the split between ``G`` and ``r`` is a convention.

    Where the motion knows the sensor's position ``p`` (world, m: a position track,
    :attr:`imucal.sim.motion.KinematicState.position_m`) the field is a function of it instead:
    ``G (p - p_mean) + D(p) - D_mean`` with ``D`` the dipole's field; the means over the
    recording are left out as the pivot's offset is (they change the apparent Earth field).
    """

    name = "world_magnetic"
    scalable = ("grad_xx", "grad_yy", "grad_xy", "grad_xz", "grad_yz")
    arm_x_m: float = 0.1
    arm_y_m: float = 0.05
    arm_z_m: float = 0.1
    grad_xx: float = 0.2
    grad_yy: float = 0.1
    grad_xy: float = 0.15
    grad_xz: float = -0.1
    grad_yz: float = 0.2
    dipole_x_m: float = 0.0
    dipole_y_m: float = 0.0
    dipole_z_m: float = 0.0
    moment_x: float = 0.0
    moment_y: float = 0.0
    moment_z: float = 0.0

    def gradient(self) -> np.ndarray:
        return gradient_matrix(self.grad_xx, self.grad_yy, self.grad_xy, self.grad_xz, self.grad_yz)

    def arm(self) -> np.ndarray:
        return np.array([self.arm_x_m, self.arm_y_m, self.arm_z_m])

    def field_world(self, rotation, position: np.ndarray | None = None) -> np.ndarray:
        """The disturbance at the sensor, world axes, shape (n, 3), for ``n`` orientations
        (a scipy ``Rotation``, B -> world), or at ``n`` positions (world, m, shape (n, 3))
        when they are given."""
        if position is None:
            return rotation.apply(self.arm()) @ self.gradient().T
        p = np.asarray(position, dtype=float)
        field = (p - p.mean(axis=0)) @ self.gradient().T
        if np.any(self.moment()):
            dip = dipole_field(p, self.dipole(), self.moment())
            field = field + dip - dip.mean(axis=0)
        return field

    def dipole(self) -> np.ndarray:
        return np.array([self.dipole_x_m, self.dipole_y_m, self.dipole_z_m])

    def moment(self) -> np.ndarray:
        return np.array([self.moment_x, self.moment_y, self.moment_z])

    def on_true_signals(
        self, signals: Signals, state: KinematicState, ctx: RecordingContext
    ) -> Signals:
        field = self.field_world(state.rotation, state.position_m)
        extra = state.rotation.apply(field, inverse=True)
        return signals.with_sensor("mag", signals.mag + extra)

    def magnitude(self) -> Magnitude:
        size = float(np.linalg.norm(self.gradient()) * np.linalg.norm(self.arm()))
        return Magnitude(size, "1 (Earth field)", "|G| |r|, the position-dependent field")


@register
@dataclass(frozen=True)
class Shock(Effect):
    """Knocks and taps: short pulses in the accelerometer and the gyroscope.

    Knocks come at random (a Poisson process of ``rate_per_s``), each a half-sine of
    ``duration_s`` in a random direction (drawn apart for the two sensors) with peaks
    ``acc_peak_m_s2`` and ``gyr_peak_rad_s``, averaged over each sample period (a sensor's
    anti-alias filter: the readings' integral is the pulse's, ``2 peak duration / pi``,
    whatever its phase to the samples), added to the readings: the reference does not
    resolve a few milliseconds (the hand or the mount takes the board back; an optical system
    smooths over several frames). The knock times go to ``effects_realised`` (``times_s``).

    Parameters
    ----------
    rate_per_s : float
        Knocks per second, > 0. Realistic 0.2 (one every 5 s while tapping).
    acc_peak_m_s2 : float
        Peak specific force of a knock. Realistic 30 m/s^2 (3 g: a tap detector's usual
        threshold, e.g. the ADXL345's tap function set at 3 g and < 10 ms **[recalled]**).
    gyr_peak_rad_s : float
        Peak rate. Realistic 2 rad/s: 3 g at 5 cm from the board's centre is an angular
        acceleration of 600 rad/s^2, over a 5 ms half-sine a rate of 1.9 rad/s **[computed]**.
    duration_s : float
        Length of the half-sine, > 0. Realistic 5 ms.

    Notes
    -----
    Magnitude: ``gyr_peak_rad_s`` (what a gyroscope compared with a reference measures); a
    scaled shock scales both peaks.
    """

    name = "shock"
    scalable = ("acc_peak_m_s2", "gyr_peak_rad_s")
    rate_per_s: float = 0.2
    acc_peak_m_s2: float = 30.0
    gyr_peak_rad_s: float = 2.0
    duration_s: float = 0.005

    def __post_init__(self) -> None:
        for key in ("rate_per_s", "duration_s"):
            if not getattr(self, key) > 0:
                raise ValueError(f"shock {key} must be > 0, got {getattr(self, key)}")
        for key in ("acc_peak_m_s2", "gyr_peak_rad_s"):
            if not getattr(self, key) >= 0:
                raise ValueError(f"shock {key} must be >= 0, got {getattr(self, key)}")

    def on_readings(
        self, readings: Signals, true: Signals, state: KinematicState, ctx: RecordingContext
    ) -> Signals:
        rng = ctx.rng(f"effect/{self.name}")
        t = np.asarray(state.t_s, dtype=float)
        span = t[-1] - t[0]
        times = np.sort(rng.uniform(t[0], t[-1], rng.poisson(self.rate_per_s * span)))
        ctx.record(self.name, "times_s", times.tolist())
        acc, gyr = readings.acc.copy(), readings.gyr.copy()
        dirs_acc, dirs_gyr = random_unit(rng, len(times)), random_unit(rng, len(times))
        dt = 1.0 / ctx.rate_hz
        d = self.duration_s

        def area(tau: np.ndarray) -> np.ndarray:
            """Integral of the unit half-sine from its start to ``tau`` (clipped), s."""
            return d / np.pi * (1.0 - np.cos(np.pi * np.clip(tau, 0.0, d) / d))

        for t0, d_acc, d_gyr in zip(times, dirs_acc, dirs_gyr, strict=True):
            lo, hi = np.searchsorted(t, [t0, t0 + d + dt])
            # each reading carries the pulse averaged over its sample period (the sensor's
            # anti-alias filter): the readings' integral is the pulse's at any phase
            shape = ((area(t[lo:hi] - t0) - area(t[lo:hi] - dt - t0)) / dt)[:, None]
            acc[lo:hi] += self.acc_peak_m_s2 * shape * d_acc
            gyr[lo:hi] += self.gyr_peak_rad_s * shape * d_gyr
        return Signals(acc, gyr, readings.mag)

    def magnitude(self) -> Magnitude:
        return Magnitude(self.gyr_peak_rad_s, "rad/s", "peak rate of a knock in the gyroscope")


@register
@dataclass(frozen=True)
class Vibration(Effect):
    """A narrow band in the accelerometer and gyroscope: a machine or a robot's drives.

    A sinusoid of ``freq_hz`` along a direction drawn per recording (apart for each sensor),
    with a random phase and amplitudes ``acc_amp_m_s2`` and ``gyr_amp_rad_s``, added to the
    readings: an angular vibration of ``gyr_amp / (2 pi f)`` (0.1 mrad at the defaults) is below
    what an orientation reference resolves. The direction and phase go to ``effects_realised``.

    Parameters
    ----------
    freq_hz : float
        Frequency, > 0. Realistic 45 Hz (effects.md #18: motor and gear lines; a 2,700 rpm
        drive).
    acc_amp_m_s2 : float
        Amplitude of the specific force. Realistic 1 m/s^2: machinery vibration of 2-4 mm/s
        RMS velocity (the "acceptable" zones of ISO 10816 for small machines **[recalled]**)
        is 0.8-1.6 m/s^2 amplitude at 45 Hz **[computed]**.
    gyr_amp_rad_s : float
        Amplitude of the rate. Realistic 0.03 rad/s: 1 m/s^2 at the end of a 10 cm mount
        flexing about its base is 0.12 mrad at 45 Hz, a rate of 0.035 rad/s **[computed]**.

    Notes
    -----
    Magnitude: ``gyr_amp_rad_s``; a scaled vibration scales both amplitudes.
    """

    name = "vibration"
    scalable = ("acc_amp_m_s2", "gyr_amp_rad_s")
    freq_hz: float = 45.0
    acc_amp_m_s2: float = 1.0
    gyr_amp_rad_s: float = 0.03

    def __post_init__(self) -> None:
        if not self.freq_hz > 0:
            raise ValueError(f"vibration freq_hz must be > 0 Hz, got {self.freq_hz}")
        for key in ("acc_amp_m_s2", "gyr_amp_rad_s"):
            if not getattr(self, key) >= 0:
                raise ValueError(f"vibration {key} must be >= 0, got {getattr(self, key)}")

    def on_readings(
        self, readings: Signals, true: Signals, state: KinematicState, ctx: RecordingContext
    ) -> Signals:
        rng = ctx.rng(f"effect/{self.name}")
        dirs = random_unit(rng, 2)
        phase = float(rng.uniform(0.0, 2 * np.pi))
        ctx.record(self.name, "direction_acc", dirs[0].tolist())
        ctx.record(self.name, "direction_gyr", dirs[1].tolist())
        ctx.record(self.name, "phase_rad", phase)
        wave = np.sin(2 * np.pi * self.freq_hz * np.asarray(state.t_s) + phase)[:, None]
        return Signals(
            readings.acc + self.acc_amp_m_s2 * wave * dirs[0],
            readings.gyr + self.gyr_amp_rad_s * wave * dirs[1],
            readings.mag,
        )

    def magnitude(self) -> Magnitude:
        return Magnitude(self.gyr_amp_rad_s, "rad/s", "amplitude of the line in the gyroscope")
