"""Kalibr: the IMU noise file ``imu.yaml`` and the intrinsics of its ``scale-misalignment`` model.

Conventions, from Kalibr's source (ethz-asl/kalibr, ``aslam_offline_calibration/kalibr/python``):

* ``imu.yaml`` keys and units (``kalibr_common/ConfigReader.py``, ``ImuParameters``): the four
  noise values are continuous-time densities, per sqrt(Hz); Kalibr discretises them with
  ``update_rate`` (``sigma_d = density / sqrt(1 / update_rate)``).
* ``scale-misalignment`` (``kalibr_imu_camera_calibration/IccSensors.py``,
  ``IccScaledMisalignedImu``): ``a_m = M_a a_i + b_a`` and
  ``w_m = M_g C_gyro_i w_i + A C_gyro_i a_i + b_g``, ``M_a`` and ``M_g`` lower triangular,
  ``C_gyro_i`` a rotation, in the IMU frame i (the accelerometer's). Written under
  ``accelerometers: M`` and ``gyroscopes: M, A, C_gyro_i``.

Ours is ``v_B = K (v_m - b)`` in the platform frame B. Inverted: ``K_a^-1 = M_a R_iB`` (lower
times rotation) fixes i (``v_i = R_iB v_B``), and ``K_g^-1 R_iB^T = M_g C_gyro_i``. Our
g-sensitivity (``w_B = K_g (w_m - b) - G a_B``, :mod:`imucal.modelterms`) adds
``K_g^-1 G a_B = K_g^-1 G R_iB^T a_i`` to ``w_m``: ``A = K_g^-1 G R_iB^T C_gyro_i^T`` (zero when
the model has none). Kalibr estimates the biases itself (a spline); ours are
given as ``imucal_acc_bias`` and ``imucal_gyr_bias`` with ``imucal_R_i_B``, keys Kalibr ignores.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from imucal.calibration import SensorCalibration
from imucal.export.model import (
    RECOMMENDED_INFLATION,
    ROSTOPIC,
    NoiseParameters,
    lower_times_rotation,
    matrix_list,
)

MODEL = "scale-misalignment"


def kalibr_imu(noise: NoiseParameters, *, rostopic: str = ROSTOPIC) -> dict:
    """Kalibr's IMU configuration (``imu.yaml``): noise densities, random walks, rate, topic."""
    return {
        "accelerometer_noise_density": noise.acc_noise_density,
        "accelerometer_random_walk": noise.acc_random_walk,
        "gyroscope_noise_density": noise.gyr_noise_density,
        "gyroscope_random_walk": noise.gyr_random_walk,
        "rostopic": rostopic,
        "update_rate": noise.update_rate_hz,
    }


def kalibr_intrinsics(
    calibration: Mapping[str, SensorCalibration], g_sensitivity: np.ndarray | None = None
) -> dict:
    """The scale-misalignment matrices of our calibration, and the frame they live in.

    Parameters
    ----------
    calibration : mapping of str to SensorCalibration
        'acc' and 'gyr'.
    g_sensitivity : ndarray, shape (3, 3), optional
        Our ``G`` (rad/s per m/s^2, frame B); None for none.

    Returns
    -------
    dict
        ``M_accel`` (3, 3), ``M_gyro`` (3, 3), ``C_gyro_i`` (3, 3), ``A`` (3, 3),
        ``R_i_B`` (3, 3): ``v_i = R_i_B v_B``.
    """
    acc, gyr = calibration["acc"], calibration["gyr"]
    g = np.zeros((3, 3)) if g_sensitivity is None else np.asarray(g_sensitivity, dtype=float)
    m_accel, r_i_b = lower_times_rotation(np.linalg.inv(acc.matrix))
    m_gyro, c_gyro_i = lower_times_rotation(np.linalg.inv(gyr.matrix) @ r_i_b.T)
    a = np.linalg.solve(gyr.matrix, g) @ r_i_b.T @ c_gyro_i.T
    return {"M_accel": m_accel, "M_gyro": m_gyro, "C_gyro_i": c_gyro_i, "A": a,
            "R_i_B": r_i_b}  # fmt: skip


def kalibr_imu_chain(
    calibration: Mapping[str, SensorCalibration],
    noise: NoiseParameters,
    *,
    g_sensitivity: np.ndarray | None = None,
    rostopic: str = ROSTOPIC,
) -> dict:
    """The ``imu0`` entry as Kalibr writes it for the scale-misalignment model
    (``g_sensitivity``: our ``G``, see :func:`kalibr_intrinsics`)."""
    k = kalibr_intrinsics(calibration, g_sensitivity)
    imu0 = {
        "T_i_b": matrix_list(np.eye(4)),
        **kalibr_imu(noise, rostopic=rostopic),
        "time_offset": 0.0,
        "model": MODEL,
        "accelerometers": {"M": matrix_list(k["M_accel"])},
        "gyroscopes": {
            "M": matrix_list(k["M_gyro"]),
            "A": matrix_list(k["A"]),
            "C_gyro_i": matrix_list(k["C_gyro_i"]),
        },
        "imucal_acc_bias": [float(v) for v in calibration["acc"].bias],
        "imucal_gyr_bias": [float(v) for v in calibration["gyr"].bias],
        "imucal_R_i_B": matrix_list(k["R_i_B"]),
    }
    return {"imu0": imu0}


def noise_header(noise: NoiseParameters) -> list[str]:
    """Comment lines that say where each noise value comes from and what to inflate."""
    return [
        "Noise values: IEEE 952 fit of the Allan deviation of the static recording (imucal).",
        f"  accelerometer_noise_density: {noise.note('acc_noise_density')}, m/s^2/sqrt(Hz)",
        f"  accelerometer_random_walk:   {noise.note('acc_random_walk')}, m/s^3/sqrt(Hz)",
        f"  gyroscope_noise_density:     {noise.note('gyr_noise_density')}, rad/s/sqrt(Hz)",
        f"  gyroscope_random_walk:       {noise.note('gyr_random_walk')}, rad/s^2/sqrt(Hz)",
        "These are the sensor's own values, NOT inflated. Inflate them before use for the",
        f"errors the model leaves out: {RECOMMENDED_INFLATION}.",
    ]
