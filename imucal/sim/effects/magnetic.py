"""Effects on the magnetometer: mag_latency, platform_magnetic."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from imucal.sim.effects.base import Effect, Magnitude, RecordingContext, register
from imucal.sim.motion import KinematicState, Motion, evaluate_motion, piece_angle
from imucal.sim.sensors import Signals

#: Largest angle (deg) between a piece's rotation axis and the vertical for the platform's
#: outer (vertical) axis to be the one turning (``platform_magnetic``).
VERTICAL_TOLERANCE_DEG = 5.0


@register
@dataclass(frozen=True)
class MagLatency(Effect):
    """The magnetometer samples on its own slower clock, with a delay; packets hold its output.

    The magnetometer takes a sample at ``t_j = phase + j / rate_hz`` (module clock); a packet
    of module sample ``k`` (time ``t_k = k / rate``) carries the latest sample with
    ``t_j <= t_k - delay_s``, noise included (sample-and-hold). Acc and gyro stay at the packet
    rate; the packets still carry a magnetometer value on every 10th row. The phase is drawn
    per recording, uniform in ``[0, 1 / rate_hz)``, and recorded in ``effects_realised``.

    The age of a reported value is ``delay_s`` plus a uniform ``[0, 1 / rate_hz)``, so during a
    rotation the field in B lags by the mean age ``delay_s + 1 / (2 rate_hz)``: the residual is
    about ``age * (omega x m)`` (perpendicular to the rotation axis, proportional to the rate,
    antisymmetric in the direction) and vanishes when static. Below 10 Hz consecutive reported
    values repeat (a staircase at ``rate_hz``).

    Parameters
    ----------
    rate_hz : float
        Magnetometer output rate (Hz), > 0. Realistic: 75 Hz (HMC5883L's fastest continuous
        mode; AK8963 8 or 100 Hz).
    delay_s : float
        Conversion and read-out delay (s), >= 0. Realistic: 20 ms (effects.md #11).

    Notes
    -----
    The held field is exact for the Earth's field (orientation from the motion at the sample
    instant); fields added by earlier effects (``platform_magnetic``) are interpolated linearly
    in the world frame between packet samples.
    """

    name = "mag_latency"
    priority = 50  # after the effects that change the true field, before saturation
    rate_hz: float = 75.0
    delay_s: float = 0.02

    def __post_init__(self) -> None:
        if not self.rate_hz > 0:
            raise ValueError(f"mag_latency rate_hz must be > 0 Hz, got {self.rate_hz}")
        if not self.delay_s >= 0:
            raise ValueError(f"mag_latency delay_s must be >= 0 s, got {self.delay_s}")

    def held(self, t_s: np.ndarray, phase_s: float) -> tuple[np.ndarray, np.ndarray]:
        """Index ``j`` and time (s) of the magnetometer sample a packet at ``t_s`` (module
        time, shape (n,)) holds, for the recording's phase ``phase_s``; ``t_s`` minus the time is
        the age of the reported value (its mean over the rows that carry a field is what a
        delay estimated from those rows measures: with the field on every 10th packet only a
        few ages recur, and their mean depends on the phase by up to ``1 / (4 rate_hz)``)."""
        j = np.floor((np.asarray(t_s) - self.delay_s - phase_s) * self.rate_hz).astype(np.int64)
        return j, phase_s + j / self.rate_hz

    def _held(self, n: int, ctx: RecordingContext) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`held` for the ``n`` packets of a recording, its phase drawn and recorded."""
        phase = float(ctx.rng(f"effect/{self.name}").uniform(0.0, 1.0 / self.rate_hz))
        ctx.record(self.name, "phase_s", phase)
        return self.held(np.arange(n) / ctx.rate_hz, phase)

    def on_true_signals(
        self, signals: Signals, state: KinematicState, ctx: RecordingContext
    ) -> Signals:
        motion: Motion = ctx.require(self.name, "motion")
        _, t_held = self._held(len(signals.mag), ctx)
        world = state.rotation.apply(signals.mag)
        world_held = np.column_stack([np.interp(t_held, state.t_s, world[:, i]) for i in range(3)])
        rot_held = evaluate_motion(motion, t_held).rotation
        return signals.with_sensor("mag", rot_held.apply(world_held, inverse=True))

    def on_readings(
        self, readings: Signals, true: Signals, state: KinematicState, ctx: RecordingContext
    ) -> Signals:
        j, _ = self._held(len(true.mag), ctx)
        first = np.searchsorted(j, j, side="left")  # j is non-decreasing
        return readings.with_sensor("mag", readings.mag[first])

    def scaled(self, factor: float) -> Effect:
        """Mean age times ``factor``: ``delay_s`` times it, ``rate_hz`` divided by it."""
        if not factor > 0:
            raise ValueError(f"effect {self.name!r}: scale factor must be > 0, got {factor}")
        return dataclasses.replace(
            self, delay_s=self.delay_s * factor, rate_hz=self.rate_hz / factor
        )

    def magnitude(self) -> Magnitude:
        return Magnitude(
            self.delay_s + 0.5 / self.rate_hz,
            "s",
            "mean age of the reported field, delay_s + 1 / (2 rate_hz)",
        )


def platform_yaw(motion: Motion, t_s: np.ndarray) -> np.ndarray:
    """Angle (rad) the platform's vertical (outer) axis has turned since the recording start.

    The platform turns its outer axis during the pieces whose rotation axis is vertical in the
    world (within ``VERTICAL_TOLERANCE_DEG``), signed about world +z; pieces about a horizontal
    axis are turned by the inner gimbal(s) and leave it where it is.

    Parameters
    ----------
    motion : Motion
    t_s : ndarray, shape (n,)
        Module times (s).

    Returns
    -------
    ndarray, shape (n,)
    """
    t = np.asarray(t_s, dtype=float)
    yaw = np.zeros_like(t)
    cos_tol = np.cos(np.radians(VERTICAL_TOLERANCE_DEG))
    for piece in motion.pieces:
        if piece.profile == "hold":
            continue
        up = piece.start.apply(piece.axis_b)[2]
        if abs(up) < cos_tol:
            continue
        yaw += np.sign(up) * piece_angle(piece, np.clip(t - piece.start_s, 0.0, None))
    return yaw


@register
@dataclass(frozen=True)
class PlatformMagnetic(Effect):
    """A stray field of the 3-D platform's motors and steel, fixed to the platform, not to B.

    Model (rotation3d only, the recording made on the 3-D platform). The platform is taken as
    an outer axis that is vertical (it turns the module about the world vertical: the 90-deg
    transitions and phase z) carrying inner gimbal(s) that turn it about horizontal axes
    (phases x and y). The motors and steel of the inner gimbal ride on the outer axis, so their
    field is constant in the frame P of the outer axis: ``d_world(t) = Rz(psi(t)) d`` with
    ``psi`` the outer axis's angle since the recording start (:func:`platform_yaw`) and ``d``
    the field in world axes at the start. A motor's current is proportional to its torque, so
    to the angular acceleration; its field points along its axis: ``c * omega_dot`` (B). In B:

    ``m_B = R^T (m_earth + Rz(psi) d) + c * omega_dot_b``

    A field fixed in the world would only change the apparent Earth field (constant norm, no
    signature); one fixed in B is a hard iron, absorbed by the ellipsoid fit. The field fixed in
    P is neither: between static poses at different ``psi`` (before and after a 90-deg
    transition) ``|m|`` after the true calibration differs, ``|m_earth + Rz(psi) d|``; within a
    horizontal-axis phase the samples lie on a sphere of that radius, so phases at different
    platform angles do not share one ellipsoid, and the residuals correlate with ``psi`` and,
    through the current term, with the spin-up and spin-down.

    Parameters
    ----------
    field_x, field_y, field_z : float
        ``d``, normalised to the Earth's field (1 = about 48 uT). Realistic (effects.md #12:
        uT to tens of uT near motors): ``|d|`` = 0.1 (about 5 uT).
    current_per_rad_s2 : float
        ``c``, normalised field per rad/s^2 of angular acceleration. Realistic: 0.02 (about
        1 uT at the platform's 1 rad/s^2).

    Notes
    -----
    The reference (MTx) is assumed far enough from the motors not to see it.
    """

    name = "platform_magnetic"
    scalable = ("field_x", "field_y", "field_z", "current_per_rad_s2")
    field_x: float = 0.06
    field_y: float = -0.04
    field_z: float = 0.07
    current_per_rad_s2: float = 0.02

    def on_true_signals(
        self, signals: Signals, state: KinematicState, ctx: RecordingContext
    ) -> Signals:
        if ctx.recording != "rotation3d":
            return signals
        motion: Motion = ctx.require(self.name, "motion")
        d = np.array([self.field_x, self.field_y, self.field_z])
        d_world = Rotation.from_euler("z", platform_yaw(motion, state.t_s)[:, None]).apply(d)
        extra = state.rotation.apply(d_world, inverse=True)
        extra = extra + self.current_per_rad_s2 * state.omega_dot_b
        return signals.with_sensor("mag", signals.mag + extra)

    def magnitude(self) -> Magnitude:
        d = float(np.linalg.norm([self.field_x, self.field_y, self.field_z]))
        return Magnitude(d, "1 (Earth field)", "|d|, platform-fixed field / Earth field")
