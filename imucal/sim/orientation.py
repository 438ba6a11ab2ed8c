"""A hand-held session recorded with an orientation reference (motion capture, robot).

The body turns with a smooth random rate about all axes, with rests between bouts; the module's
gyroscope and accelerometer sample it on the module clock, the reference samples its orientation
on its own clock (another rate, an offset and a drift), with orientation noise and tracking
gaps (NaN rows). Used by the tests of :mod:`imucal.validation.orientation` and
:mod:`imucal.fits.reference`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from imucal.orientation import (
    integrate_rates,
    quat_conjugate,
    quat_from_matrix,
    quat_from_rotvec,
    quat_multiply,
    quat_rotate,
)
from imucal.sim.effects import RecordingContext
from imucal.sim.motion import KinematicState
from imucal.sim.sensors import Signals

#: Dip of the simulated field below the horizon, deg.
FIELD_DIP_DEG = 60.0
#: The simulated field in the world (ENU, unit norm): north (+y) and down.
FIELD_WORLD = np.array([0.0, np.cos(np.radians(FIELD_DIP_DEG)), -np.sin(np.radians(FIELD_DIP_DEG))])


@dataclass(frozen=True)
class OrientationSession:
    """Simulated module and reference series with the truth.

    Attributes
    ----------
    t_module : ndarray, shape (n,)
        Module times, s.
    gyr, acc, mag : ndarray, shape (n, 3)
        Gyroscope, accelerometer and magnetometer readings (rad/s, m/s^2, field of unit
        norm).
    t_reference : ndarray, shape (m,)
        Reference times on its clock: ``t_ref = offset_s + (1 + drift_ppm 1e-6) t_module``.
    quat_reference : ndarray, shape (m, 4)
        Body -> world (``up`` = +z), scalar first; NaN rows in the gaps.
    matrix, bias : ndarray
        Truth: ``omega_B = matrix @ (gyr - bias)``.
    mounting : ndarray, shape (3, 3)
        Truth: ``omega_B = mounting @ omega_body``.
    offset_s, drift_ppm : float
    rests_s : list of (float, float)
        Module-clock rests.
    realised : dict
        The effects' random draws (effect -> ``moves`` -> key -> value), as in truth.json.
    pos_reference : ndarray, shape (m, 3), or None
        With ``arm_m``: the body's position at the reference's samples (world, m; NaN rows in
        the gaps).
    """

    t_module: np.ndarray
    gyr: np.ndarray
    acc: np.ndarray
    mag: np.ndarray
    t_reference: np.ndarray
    quat_reference: np.ndarray
    matrix: np.ndarray
    bias: np.ndarray
    mounting: np.ndarray
    offset_s: float
    drift_ppm: float
    rests_s: list
    realised: dict = field(default_factory=dict)
    pos_reference: np.ndarray | None = None


def simulate_orientation_session(
    seed: int,
    *,
    matrix: np.ndarray,
    bias: np.ndarray,
    mounting: np.ndarray,
    duration_s: float = 120.0,
    module_rate_hz: float = 200.0,
    reference_rate_hz: float = 120.0,
    offset_s: float = 0.0,
    drift_ppm: float = 0.0,
    gyro_noise_rad_s: float = 0.01,
    orientation_noise_rad: float = 0.0005,
    gaps: int = 5,
    gap_s: float = 1.0,
    rate_rad_s: float = 2.0,
    acc_matrix: np.ndarray | None = None,
    acc_bias: np.ndarray | None = None,
    acc_noise_m_s2: float = 0.0,
    mag_matrix: np.ndarray | None = None,
    mag_bias: np.ndarray | None = None,
    reference_jitter_s: float = 0.0,
    axis_weights: np.ndarray | None = None,
    rest_s: float = 3.0,
    moves: str = "hand",
    mag_noise: float = 0.0,
    effects: tuple = (),
    arm_m: np.ndarray | None = None,
) -> OrientationSession:
    """Simulate one session (all rates rad/s, times s).

    The body rate is a sum of sinusoids (0.05-1.5 Hz) per axis, scaled to ``rate_rad_s`` RMS,
    switched off in rests of ``rest_s`` every 20 s (smooth ramps). Gyroscope readings are
    ``matrix^-1 mounting omega_body + bias`` plus white noise; the reference adds a random
    rotation of ``orientation_noise_rad`` RMS per axis to each orientation. The accelerometer
    reads gravity only (``9.81`` m/s^2 along up, in B), ideal unless ``acc_matrix`` /
    ``acc_bias`` / ``acc_noise_m_s2`` give its errors (``acc_B = acc_matrix (acc - acc_bias)``).
    The magnetometer reads a constant field of unit norm (:data:`FIELD_WORLD`, dip
    :data:`FIELD_DIP_DEG` below the horizon towards north, +y), noise-free, ideal unless
    ``mag_matrix`` / ``mag_bias`` give its errors (``mag_B = mag_matrix (mag - mag_bias)``).
    The reference's samples are taken at their time stamps plus white jitter of
    ``reference_jitter_s`` (its own random stream: the other draws do not change).
    ``axis_weights`` (shape (3,)) multiplies the body rate per axis after that scaling, e.g.
    ``(1, 1, 0.02)`` for a motion that barely turns about the body's z axis. ``rest_s`` is
    the length of each rest (a robot's rests between moves can be about 1 s).

    ``moves="robot"`` replaces the hand's motion by a robot's (:func:`robot_moves`: smooth
    point-to-point turns with rests of about 1 s; ``rate_rad_s`` is then not used).
    ``mag_noise`` adds white noise (normalised field) to the magnetometer. ``effects`` are
    simulator effects (:mod:`imucal.sim.effects`) acting on the true signals in B and on the
    readings (``on_true_signals``, ``on_readings``; recording name ``moves``, their own random
    streams), e.g. ``world_magnetic``, ``shock``, ``vibration``. ``arm_m`` (shape (3,), m, body
    frame) puts the body at ``R(t) arm_m`` from a pivot at the world's origin (a hand's wrist, a
    robot's flange): the effects get that position track, the session its values at the
    reference's samples (``pos_reference``, exact: a position reference's noise is not drawn).
    """
    if moves not in ("hand", "robot"):
        raise ValueError(f"moves must be 'hand' or 'robot', got {moves!r}")
    rng = np.random.default_rng(seed)
    dt_fine = 1e-3
    t_fine = np.arange(0.0, duration_s + 1.0, dt_fine)
    freqs = rng.uniform(0.05, 1.5, (3, 6))
    phases = rng.uniform(0, 2 * np.pi, (3, 6))
    amps = rng.normal(0, 1, (3, 6))

    def rate(t: np.ndarray) -> np.ndarray:
        w = np.einsum(
            "ak,akn->na", amps, np.sin(2 * np.pi * freqs[:, :, None] * t + phases[:, :, None])
        )
        phase = np.mod(t, 20.0)
        # rest for rest_s every 20 s (cosine ramps of 1 s)
        env = np.clip(np.minimum(phase - rest_s, 20.0 - phase), 0.0, 1.0)
        env = 0.5 - 0.5 * np.cos(np.pi * env)
        return w * env[:, None]

    scale = rate_rad_s / np.sqrt(np.mean(rate(t_fine) ** 2))
    if axis_weights is not None:
        scale = scale * np.asarray(axis_weights, dtype=float)
    if moves == "robot":
        rate, robot_rests = robot_moves(np.random.default_rng([seed, 2]), duration_s + 1.0)
        scale = 1.0
    w_fine = scale * rate(t_fine)
    q_fine = integrate_rates(t_fine, w_fine)  # body -> start frame
    q0 = quat_from_rotvec(rng.normal(0, 1, 3))
    q_fine = quat_multiply(q0, q_fine)
    t_m = np.arange(0.0, duration_s, 1.0 / module_rate_hz)
    w_body = scale * rate(t_m)
    gyr_b = w_body @ np.asarray(mounting).T
    up = np.array([0.0, 0.0, 1.0])
    idx = np.clip(np.round(t_m / dt_fine).astype(int), 0, t_fine.size - 1)
    q_mount = quat_from_matrix(mounting)
    acc = 9.81 * quat_rotate(quat_multiply(q_mount, quat_conjugate(q_fine[idx])), up)
    mag = quat_rotate(quat_multiply(q_mount, quat_conjugate(q_fine[idx])), FIELD_WORLD)
    ctx = RecordingContext("moves", module_rate_hz, 0.0, {}, seed)
    if effects:
        # B -> world: the body's orientation, B = mounting body
        rotation = (
            Rotation.from_quat(q_fine[idx][:, [1, 2, 3, 0]])
            * Rotation.from_matrix(np.asarray(mounting, dtype=float)).inv()
        )
        where = (
            None
            if arm_m is None
            else quat_rotate(q_fine[idx], np.tile(np.asarray(arm_m, float), (idx.size, 1)))
        )
        state = KinematicState(t_m, rotation, gyr_b, np.zeros_like(gyr_b), where)
        true = Signals(acc, gyr_b, mag)
        for effect in effects:
            true = effect.on_true_signals(true, state, ctx)
        acc, gyr_b, mag = true.acc, true.gyr, true.mag
    gyr = np.linalg.solve(matrix, gyr_b.T).T + bias + rng.normal(0, gyro_noise_rad_s, gyr_b.shape)
    if acc_matrix is not None:
        acc = np.linalg.solve(acc_matrix, acc.T).T
    if acc_bias is not None:
        acc = acc + acc_bias
    acc = acc + rng.normal(0, 1, acc.shape) * acc_noise_m_s2
    if mag_matrix is not None:
        mag = np.linalg.solve(mag_matrix, mag.T).T
    if mag_bias is not None:
        mag = mag + mag_bias
    if mag_noise > 0:
        mag = mag + np.random.default_rng([seed, 3]).normal(0.0, mag_noise, mag.shape)
    if effects:
        readings = Signals(acc, gyr, mag)
        for effect in effects:
            readings = effect.on_readings(readings, true, state, ctx)
        acc, gyr, mag = readings.acc, readings.gyr, readings.mag
    # reference clock: sample k at t_ref = k / rate, module time (t_ref - offset) / (1 + drift)
    t_ref_all = np.arange(
        0.0, offset_s + duration_s * (1 + drift_ppm * 1e-6), 1.0 / reference_rate_hz
    )
    t_mod_of_ref = (t_ref_all - offset_s) / (1 + drift_ppm * 1e-6)
    inside = (t_mod_of_ref >= 0.2) & (t_mod_of_ref <= duration_s - 0.2)
    t_ref, t_mod_of_ref = t_ref_all[inside], t_mod_of_ref[inside]
    taken = t_mod_of_ref + np.random.default_rng([seed, 1]).normal(
        0.0, reference_jitter_s, t_mod_of_ref.shape
    )
    pos = taken / dt_fine
    i = np.floor(pos).astype(int)
    frac = (pos - i)[:, None]
    q_ref = (1 - frac) * q_fine[i] + frac * q_fine[i + 1]
    q_ref /= np.linalg.norm(q_ref, axis=1, keepdims=True)
    p_ref = (
        None
        if arm_m is None
        else quat_rotate(q_ref, np.tile(np.asarray(arm_m, float), (len(q_ref), 1)))
    )
    noise = quat_from_rotvec(rng.normal(0, orientation_noise_rad, (t_ref.size, 3)))
    q_ref = quat_multiply(q_ref, noise)
    for start in rng.uniform(t_ref[0] + 5, t_ref[-1] - 5, gaps):
        q_ref[(t_ref >= start) & (t_ref < start + gap_s)] = np.nan
    if p_ref is not None:
        p_ref[~np.isfinite(q_ref).all(axis=1)] = np.nan
    rests = [(s + 0.1 * rest_s, s + 0.9 * rest_s) for s in np.arange(0.0, duration_s - 3.0, 20.0)]
    if moves == "robot":
        rests = [(a + 0.1, b - 0.1) for a, b in robot_rests if b < duration_s]
    return OrientationSession(
        t_module=t_m,
        gyr=gyr,
        acc=acc,
        mag=mag,
        t_reference=t_ref,
        quat_reference=q_ref,
        matrix=np.asarray(matrix, dtype=float),
        bias=np.asarray(bias, dtype=float),
        mounting=np.asarray(mounting, dtype=float),
        offset_s=offset_s,
        drift_ppm=drift_ppm,
        rests_s=rests,
        realised=ctx.realised,
        pos_reference=p_ref,
    )


def robot_moves(rng: np.random.Generator, duration_s: float) -> tuple:
    """A robot's motion: smooth point-to-point turns with rests between them.

    Each move turns the body about an axis drawn uniformly in the body frame by 20-90 deg in
    2-4 s with a minimum-jerk profile (rate ``angle s'(tau) / T``, ``s = 10 tau^3 - 15 tau^4 +
    6 tau^5``: zero rate and acceleration at both ends), then rests for 0.8-1.2 s.

    Parameters
    ----------
    rng : numpy Generator
    duration_s : float
        Span to cover, s.

    Returns
    -------
    rate : callable
        ``t (n,) -> body rate (n, 3)``, rad/s.
    rests : list of (float, float)
        The rests, s.
    """
    starts, lengths, turns, rests = [], [], [], []
    t = 1.0
    rests.append((0.0, t))
    while t < duration_s:
        length = rng.uniform(2.0, 4.0)
        axis = rng.normal(size=3)
        turns.append(np.radians(rng.uniform(20.0, 90.0)) * axis / np.linalg.norm(axis))
        starts.append(t)
        lengths.append(length)
        pause = rng.uniform(0.8, 1.2)
        rests.append((t + length, t + length + pause))
        t += length + pause
    starts, lengths, turns = np.array(starts), np.array(lengths), np.array(turns)

    def rate(t_s: np.ndarray) -> np.ndarray:
        t_s = np.asarray(t_s, dtype=float)
        k = np.clip(np.searchsorted(starts, t_s, side="right") - 1, 0, len(starts) - 1)
        tau = (t_s - starts[k]) / lengths[k]
        inside = (tau >= 0) & (tau <= 1)
        tau = np.where(inside, tau, 0.0)
        speed = np.where(inside, 30 * tau**2 - 60 * tau**3 + 30 * tau**4, 0.0) / lengths[k]
        return speed[:, None] * turns[k]

    return rate, rests
