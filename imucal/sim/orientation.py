"""A hand-held session recorded with an orientation reference (motion capture, robot).

The body turns with a smooth random rate about all axes, with rests between bouts; the module's
gyroscope and accelerometer sample it on the module clock, the reference samples its orientation
on its own clock (another rate, an offset and a drift), with orientation noise and tracking
gaps (NaN rows). Used by the tests of :mod:`imucal.validation.orientation` and
:mod:`imucal.fits.reference`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from imucal.orientation import (
    integrate_rates,
    quat_conjugate,
    quat_from_matrix,
    quat_from_rotvec,
    quat_multiply,
    quat_rotate,
)

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
    """
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
    w_fine = scale * rate(t_fine)
    q_fine = integrate_rates(t_fine, w_fine)  # body -> start frame
    q0 = quat_from_rotvec(rng.normal(0, 1, 3))
    q_fine = quat_multiply(q0, q_fine)
    t_m = np.arange(0.0, duration_s, 1.0 / module_rate_hz)
    w_body = scale * rate(t_m)
    gyr_b = w_body @ np.asarray(mounting).T
    gyr = np.linalg.solve(matrix, gyr_b.T).T + bias + rng.normal(0, gyro_noise_rad_s, gyr_b.shape)
    up = np.array([0.0, 0.0, 1.0])
    idx = np.clip(np.round(t_m / dt_fine).astype(int), 0, t_fine.size - 1)
    q_mount = quat_from_matrix(mounting)
    acc = 9.81 * quat_rotate(quat_multiply(q_mount, quat_conjugate(q_fine[idx])), up)
    if acc_matrix is not None:
        acc = np.linalg.solve(acc_matrix, acc.T).T
    if acc_bias is not None:
        acc = acc + acc_bias
    acc = acc + rng.normal(0, 1, acc.shape) * acc_noise_m_s2
    mag = quat_rotate(quat_multiply(q_mount, quat_conjugate(q_fine[idx])), FIELD_WORLD)
    if mag_matrix is not None:
        mag = np.linalg.solve(mag_matrix, mag.T).T
    if mag_bias is not None:
        mag = mag + mag_bias
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
    noise = quat_from_rotvec(rng.normal(0, orientation_noise_rad, (t_ref.size, 3)))
    q_ref = quat_multiply(q_ref, noise)
    for start in rng.uniform(t_ref[0] + 5, t_ref[-1] - 5, gaps):
        q_ref[(t_ref >= start) & (t_ref < start + gap_s)] = np.nan
    rests = [(s + 0.1 * rest_s, s + 0.9 * rest_s) for s in np.arange(0.0, duration_s - 3.0, 20.0)]
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
    )
