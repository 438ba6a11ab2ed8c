"""Kinematics of a recording: a timeline of rotations of frame B, evaluated analytically.

A :class:`Motion` is a sequence of :class:`Piece` s that tile the time axis of one recording. Each
piece starts from a known orientation and turns frame B about one fixed axis *of B* (a body axis)
with a smooth angle profile, optionally with a small "wobble" rotation about a second body axis
that vanishes, with its rate, at both ends of the piece (hand handling), and optionally with a
:class:`Tremor` on top (a module held by hand). Orientation, body rate and
body angular acceleration are all closed-form, so the simulated gyroscope integrates exactly to
the orientation change: no numerical differentiation anywhere.

Orientation convention: ``R`` maps B to the world frame (``v_world = R v_B``); the world frame has
x towards magnetic north, z up.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

#: Angle profiles of a piece.
PROFILES = ("hold", "smooth", "ramp")


@dataclass(frozen=True)
class Tremor:
    """A small rotation ``Exp(a_x e_x) Exp(a_y e_y) Exp(a_z e_z)`` on top of a piece (body axes).

    Each angle is a sum of sinusoids, ``a_i(tau) = env(tau) sum_k A_ik sin(2 pi f_ik tau +
    phi_ik)``, under an envelope that rises from 0 to 1 over ``ramp_s`` at the start of the
    piece and falls back at its end with zero rate and zero angular acceleration at both ends
    (cycloidal ramps), so the piece still starts and ends at its nominal orientations.

    Attributes
    ----------
    amplitude_rad : ndarray, shape (3, k)
        Amplitudes ``A`` (rad) per body axis x, y, z and component.
    freq_hz : ndarray, shape (3, k)
        Frequencies ``f`` (Hz).
    phase_rad : ndarray, shape (3, k)
        Phases ``phi`` (rad).
    ramp_s : float
        Rise and fall time of the envelope (s), > 0 and at most half the piece.
    """

    amplitude_rad: np.ndarray
    freq_hz: np.ndarray
    phase_rad: np.ndarray
    ramp_s: float

    def __post_init__(self) -> None:
        shapes = {np.shape(self.amplitude_rad), np.shape(self.freq_hz), np.shape(self.phase_rad)}
        if len(shapes) != 1 or len(next(iter(shapes))) != 2 or next(iter(shapes))[0] != 3:
            raise ValueError(f"tremor arrays must share one shape (3, k), got {sorted(shapes)}")
        if not self.ramp_s > 0:
            raise ValueError(f"tremor ramp_s must be > 0 s, got {self.ramp_s}")

    def angles(
        self, tau_s: np.ndarray, duration_s: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Angles (rad), rates (rad/s), accelerations (rad/s^2), each shape (n, 3)."""
        if not 0 < 2 * self.ramp_s <= duration_s:
            raise ValueError(
                f"tremor ramp_s {self.ramp_s} s must be at most half the piece ({duration_s} s)"
            )
        tau = np.asarray(tau_s, dtype=float)[:, None, None]
        w = 2 * np.pi * np.asarray(self.freq_hz)[None]
        arg = w * tau + np.asarray(self.phase_rad)[None]
        amp = np.asarray(self.amplitude_rad)[None]
        s = (amp * np.sin(arg)).sum(-1)
        ds = (amp * w * np.cos(arg)).sum(-1)
        dds = -(amp * w**2 * np.sin(arg)).sum(-1)
        e, de, dde = _envelope(tau[:, 0, 0], duration_s, self.ramp_s)
        e, de, dde = e[:, None], de[:, None], dde[:, None]
        return e * s, de * s + e * ds, dde * s + 2 * de * ds + e * dds


def _envelope(tau_s: np.ndarray, duration_s: float, ramp_s: float):
    """Flat-top envelope with cycloidal ramps: value, first and second derivative, shape (n,)."""
    # a ramp is x - sin(2 pi x) / (2 pi) with x = tau / ramp_s: zero slope and curvature at 0, 1
    x = np.clip(np.minimum(tau_s, duration_s - tau_s) / ramp_s, 0.0, 1.0)
    sign = np.where(tau_s <= duration_s - tau_s, 1.0, -1.0)
    c = 2 * np.pi * x
    value = x - np.sin(c) / (2 * np.pi)
    slope = sign * (1 - np.cos(c)) / ramp_s
    curvature = 2 * np.pi * np.sin(c) / ramp_s**2
    return value, slope, curvature


@dataclass(frozen=True)
class Piece:
    """One stretch of a recording's motion.

    Attributes
    ----------
    start_s : float
        Start time (s, module clock of the recording).
    duration_s : float
        Length (s), > 0.
    start : Rotation
        Orientation (B -> world) at ``start_s``.
    axis_b : ndarray, shape (3,)
        Unit rotation axis in B (ignored for 'hold').
    angle_rad : float
        Signed total rotation angle about ``axis_b`` (rad).
    profile : str
        'hold' (static), 'smooth' (cycloidal point-to-point: zero rate and zero angular
        acceleration at both ends) or 'ramp' (cosine spin-up over ``ramp_s``, constant rate,
        cosine spin-down over ``ramp_s``; the angular acceleration is bounded by
        ``pi * rate / (2 ramp_s)``).
    ramp_s : float
        Spin-up and spin-down time of the 'ramp' profile (s).
    wobble_axis_b : ndarray, shape (3,)
        Unit axis of the wobble rotation in B.
    wobble_rad : float
        Wobble amplitude (rad); 0 for none.
    wobble_cycles : float
        Number of wobble oscillations over the piece.
    tremor : Tremor or None
        A small rotation on top of the piece (hand-held holds); None for none.
    """

    start_s: float
    duration_s: float
    start: Rotation
    axis_b: np.ndarray
    angle_rad: float = 0.0
    profile: str = "hold"
    ramp_s: float = 0.0
    wobble_axis_b: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0]))
    wobble_rad: float = 0.0
    wobble_cycles: float = 1.0
    tremor: Tremor | None = None

    def __post_init__(self) -> None:
        if self.profile not in PROFILES:
            raise ValueError(f"unknown profile {self.profile!r}; expected one of {PROFILES}")
        if not self.duration_s > 0:
            raise ValueError(f"piece duration must be > 0 s, got {self.duration_s}")
        if self.profile == "ramp" and not 0 < 2 * self.ramp_s <= self.duration_s:
            raise ValueError(
                f"ramp_s {self.ramp_s} s must be > 0 and at most half the piece "
                f"duration {self.duration_s} s"
            )

    @property
    def end_s(self) -> float:
        return self.start_s + self.duration_s

    @property
    def end(self) -> Rotation:
        """Orientation at the end of the piece (the wobble and the tremor have returned to zero)."""
        if self.profile == "hold":
            return self.start
        return self.start * Rotation.from_rotvec(self.axis_b * self.angle_rad)

    @property
    def plateau_rate_rad_s(self) -> float:
        """Constant rate of a 'ramp' piece (rad/s); 0 for the other profiles."""
        if self.profile != "ramp":
            return 0.0
        return self.angle_rad / (self.duration_s - self.ramp_s)


@dataclass(frozen=True)
class Motion:
    """Pieces that tile ``[0, duration_s]`` without gaps, in time order."""

    pieces: tuple[Piece, ...]

    def __post_init__(self) -> None:
        if not self.pieces:
            raise ValueError("a motion needs at least one piece")
        t = 0.0
        for i, p in enumerate(self.pieces):
            if not np.isclose(p.start_s, t, atol=1e-9):
                raise ValueError(f"piece {i} starts at {p.start_s} s, expected {t} s (no gaps)")
            t = p.end_s

    @property
    def duration_s(self) -> float:
        return self.pieces[-1].end_s

    @property
    def end(self) -> Rotation:
        return self.pieces[-1].end


@dataclass(frozen=True)
class KinematicState:
    """Orientation and body rates of frame B at sample times.

    Attributes
    ----------
    t_s : ndarray, shape (n,)
        Times (s) at which the motion was evaluated.
    rotation : Rotation
        ``n`` orientations B -> world.
    omega_b : ndarray, shape (n, 3)
        Angular rate of B relative to the world, in B (rad/s).
    omega_dot_b : ndarray, shape (n, 3)
        Its time derivative (rad/s^2).
    position_m : ndarray, shape (n, 3), or None
        Where B is in the world (m), when the motion knows it (a position track); None: only
        the orientation is known.
    """

    t_s: np.ndarray
    rotation: Rotation
    omega_b: np.ndarray
    omega_dot_b: np.ndarray
    position_m: np.ndarray | None = None


def _profile(piece: Piece, tau_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Angle (rad), rate (rad/s) and acceleration (rad/s^2) of a piece at local times ``tau_s``."""
    T, A = piece.duration_s, piece.angle_rad
    if piece.profile == "hold":
        z = np.zeros_like(tau_s)
        return z, z, z
    if piece.profile == "smooth":
        u = 2 * np.pi * tau_s / T
        return (
            A * (tau_s / T - np.sin(u) / (2 * np.pi)),
            A / T * (1 - np.cos(u)),
            A / T**2 * 2 * np.pi * np.sin(u),
        )
    tr = piece.ramp_s
    tc = T - 2 * tr
    w = piece.plateau_rate_rad_s
    theta = np.empty_like(tau_s)
    rate = np.empty_like(tau_s)
    acc = np.empty_like(tau_s)
    up = tau_s < tr
    down = tau_s >= tr + tc
    flat = ~up & ~down
    s = tau_s[up]
    theta[up] = w * (s / 2 - tr / (2 * np.pi) * np.sin(np.pi * s / tr))
    rate[up] = w * (1 - np.cos(np.pi * s / tr)) / 2
    acc[up] = w * np.pi / (2 * tr) * np.sin(np.pi * s / tr)
    theta[flat] = w * (tr / 2 + tau_s[flat] - tr)
    rate[flat] = w
    acc[flat] = 0.0
    s = tau_s[down] - tr - tc
    theta[down] = w * (tr / 2 + tc + s / 2 + tr / (2 * np.pi) * np.sin(np.pi * s / tr))
    rate[down] = w * (1 + np.cos(np.pi * s / tr)) / 2
    acc[down] = -w * np.pi / (2 * tr) * np.sin(np.pi * s / tr)
    return theta, rate, acc


def piece_angle(piece: Piece, tau_s: np.ndarray) -> np.ndarray:
    """Angle (rad) turned about ``piece.axis_b`` at local times ``tau_s`` (s), wobble excluded."""
    tau = np.clip(np.asarray(tau_s, dtype=float), 0.0, piece.duration_s)
    return _profile(piece, tau)[0]


def _wobble(piece: Piece, tau_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Wobble angle ``a sin^2(pi u) sin(2 pi k u)``, u = tau/T, and its two derivatives."""
    T, a, k = piece.duration_s, piece.wobble_rad, piece.wobble_cycles
    u = tau_s / T
    # envelope e = sin^2(pi u) and carrier f = sin(2 pi k u), derivatives with respect to u
    e = np.sin(np.pi * u) ** 2
    de = np.pi * np.sin(2 * np.pi * u)
    dde = 2 * np.pi**2 * np.cos(2 * np.pi * u)
    c = 2 * np.pi * k
    f, df, ddf = np.sin(c * u), c * np.cos(c * u), -(c**2) * np.sin(c * u)
    return a * e * f, a * (de * f + e * df) / T, a * (dde * f + 2 * de * df + e * ddf) / T**2


def _piece_state(piece: Piece, tau: np.ndarray) -> tuple[Rotation, np.ndarray, np.ndarray]:
    """Orientation, body rate and acceleration of a piece (tremor excluded) at local times."""
    n = tau.size
    if piece.profile == "hold":
        still = Rotation.from_quat(np.tile(piece.start.as_quat(), (n, 1)))
        return still, np.zeros((n, 3)), np.zeros((n, 3))
    theta, rate, acc = _profile(piece, tau)
    a = piece.axis_b
    main = piece.start * Rotation.from_rotvec(np.outer(theta, a))
    if piece.wobble_rad == 0.0:
        return main, np.outer(rate, a), np.outer(acc, a)
    u = piece.wobble_axis_b
    w, dw, ddw = _wobble(piece, tau)
    wob = Rotation.from_rotvec(np.outer(w, u))
    a_rot = wob.apply(a, inverse=True)
    spin = a_rot * rate[:, None]
    omega = spin + np.outer(dw, u)
    omega_dot = a_rot * acc[:, None] - np.cross(np.outer(dw, u), spin) + np.outer(ddw, u)
    return main * wob, omega, omega_dot


def _with_tremor(
    tremor: Tremor, duration_s: float, tau: np.ndarray, rot: Rotation, w_m: np.ndarray,
    dw_m: np.ndarray,
) -> tuple[Rotation, np.ndarray, np.ndarray]:  # fmt: skip
    """``R = M P`` with ``P = E_x E_y E_z`` the tremor: orientation, body rate, acceleration.

    With ``Q_i`` the product of the factors after ``E_i`` and ``w_Q`` its body rate,
    ``w_P = sum_i Q_i^T e_i a_i'`` and ``w_P' = sum_i (Q_i^T e_i a_i'' - w_Qi x Q_i^T e_i a_i')``;
    then ``w = P^T w_M + w_P`` and ``w' = P^T w_M' - w_P x P^T w_M + w_P'``.
    """
    a, da, dda = tremor.angles(tau, duration_s)
    n = tau.size
    w_p = np.zeros((n, 3))
    dw_p = np.zeros((n, 3))
    q = Rotation.from_quat(np.tile([0.0, 0.0, 0.0, 1.0], (n, 1)))
    for i in (2, 1, 0):  # from the last factor: Q_z = I, Q_y = E_z, Q_x = E_y E_z
        e = np.eye(3)[i]
        v = q.apply(e, inverse=True)
        dw_p += v * dda[:, i : i + 1] - np.cross(w_p, v * da[:, i : i + 1])
        w_p += v * da[:, i : i + 1]
        q = Rotation.from_rotvec(np.outer(a[:, i], e)) * q
    w_in = q.apply(w_m, inverse=True)
    return rot * q, w_in + w_p, q.apply(dw_m, inverse=True) - np.cross(w_p, w_in) + dw_p


def evaluate_motion(motion: Motion, t_s: np.ndarray) -> KinematicState:
    """Orientation, body rate and body angular acceleration at times ``t_s``.

    Times before 0 or after the end hold the first or last orientation at rest (a recording of
    another device may start earlier or end later).

    Parameters
    ----------
    motion : Motion
    t_s : array_like, shape (n,)
        Times in s on the recording's module clock.

    Returns
    -------
    KinematicState

    Notes
    -----
    A piece's orientation is ``R0 Exp(theta(t) a) Exp(w(t) u)`` with body axes ``a`` (motion)
    and ``u`` (wobble). Its body rate is ``Exp(w u)^T a theta' + u w'`` and the angular
    acceleration ``Exp(w u)^T a theta'' - (u w') x (Exp(w u)^T a theta') + u w''``. A
    :class:`Tremor` multiplies it on the right (see :func:`_with_tremor`).
    """
    t = np.asarray(t_s, dtype=float)
    n = t.size
    quat = np.empty((n, 4))
    omega = np.zeros((n, 3))
    omega_dot = np.zeros((n, 3))
    starts = np.array([p.start_s for p in motion.pieces])
    index = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(motion.pieces) - 1)
    before = t < 0
    after = t >= motion.duration_s
    quat[before] = motion.pieces[0].start.as_quat()
    quat[after] = motion.end.as_quat()
    for i, piece in enumerate(motion.pieces):
        sel = (index == i) & ~before & ~after
        if not np.any(sel):
            continue
        tau = t[sel] - piece.start_s
        rot, w_b, dw_b = _piece_state(piece, tau)
        if piece.tremor is not None:
            rot, w_b, dw_b = _with_tremor(piece.tremor, piece.duration_s, tau, rot, w_b, dw_b)
        quat[sel] = rot.as_quat()
        omega[sel] = w_b
        omega_dot[sel] = dw_b
    return KinematicState(t, Rotation.from_quat(quat), omega, omega_dot)


def hold(start_s: float, duration_s: float, orientation: Rotation) -> Piece:
    """A static piece."""
    return Piece(start_s, duration_s, orientation, np.zeros(3))


def turn(
    start_s: float,
    duration_s: float,
    orientation: Rotation,
    axis_b: np.ndarray,
    angle_rad: float,
    ramp_s: float | None = None,
) -> Piece:
    """Rotate about a body axis: cycloidal if ``ramp_s`` is None, else ramp + constant rate."""
    axis = np.asarray(axis_b, dtype=float)
    axis = axis / np.linalg.norm(axis)
    if ramp_s is None:
        return Piece(start_s, duration_s, orientation, axis, angle_rad, "smooth")
    return Piece(start_s, duration_s, orientation, axis, angle_rad, "ramp", ramp_s)


def move(
    start_s: float,
    duration_s: float,
    orientation: Rotation,
    target: Rotation,
    wobble_axis_b: np.ndarray | None = None,
    wobble_rad: float = 0.0,
    wobble_cycles: float = 1.0,
) -> Piece:
    """Smooth hand-handling motion from ``orientation`` to ``target`` (shortest rotation)."""
    rotvec = (orientation.inv() * target).as_rotvec()
    angle = float(np.linalg.norm(rotvec))
    axis = rotvec / angle if angle > 0 else np.array([0.0, 0.0, 1.0])
    wax = np.array([1.0, 0.0, 0.0]) if wobble_axis_b is None else np.asarray(wobble_axis_b)
    return Piece(
        start_s,
        duration_s,
        orientation,
        axis,
        angle,
        "smooth",
        wobble_axis_b=wax / np.linalg.norm(wax),
        wobble_rad=wobble_rad,
        wobble_cycles=wobble_cycles,
    )
