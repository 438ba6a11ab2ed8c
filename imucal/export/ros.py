"""ROS ``sensor_msgs/Imu``: the covariance triples of a calibrated sample.

Convention, from ``sensor_msgs/msg/Imu.msg`` (ros/common_msgs): accelerations in m/s^2,
rotational velocity in rad/s; each covariance is ``float64[9]``, row major about x, y, z; an
unknown estimate (no orientation from a 6-axis IMU) has ``-1`` in element 0.

The covariance is that of one published sample: the driver publishes ``v_B = K (v_m - b)``, so a
white noise of per-axis density ``N_j`` on the raw axes (per-sample variance ``N_j^2 f_s``, the
discretisation Kalibr uses) gives ``cov = K diag(N_j^2 f_s) K^T``. The calibration the driver
applies is written beside it (``calibration``), in our convention.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from imucal.calibration import CONVENTION, SensorCalibration
from imucal.columns import AXES
from imucal.export.model import export_rate, matrix_list
from imucal.noise import sensor_noise

#: Element 0 of a covariance that ROS readers must disregard (Imu.msg).
UNKNOWN = -1.0


def axis_densities(noise: Mapping, sensor: str) -> np.ndarray:
    """White-noise density N of each raw axis (upper bound where not resolved), shape (3,)."""
    if sensor not in noise.get("sensors", {}):
        raise ValueError(f"noise.json has no {sensor} analysis")
    axes = noise["sensors"][sensor]["axes"]
    terms = [axes[a]["terms"]["N"] for a in AXES]
    return np.array([t["value"] if t["resolved"] else t["upper_bound"] for t in terms])


def sample_covariance(
    calibration: SensorCalibration, density: np.ndarray, rate_hz: float
) -> np.ndarray:
    """Covariance of one calibrated sample, ``K diag(N^2 f_s) K^T``, shape (3, 3)."""
    k = calibration.matrix
    cov = k @ np.diag(np.asarray(density) ** 2 * rate_hz) @ k.T
    return (cov + cov.T) / 2.0  # symmetric to the last digit


def ros_imu_covariances(calibration: Mapping[str, SensorCalibration], noise: Mapping) -> dict:
    """The three covariance fields of ``sensor_msgs/Imu`` and the calibration to apply."""
    rate = export_rate(noise["rate_hz"])
    gyr = sample_covariance(calibration["gyr"], axis_densities(noise, "gyr"), rate)
    acc = sample_covariance(calibration["acc"], axis_densities(noise, "acc"), rate)
    _, ok_g = sensor_noise(noise, "gyr", "N")
    _, ok_a = sensor_noise(noise, "acc", "N")
    return {
        "orientation_covariance": [UNKNOWN] + [0.0] * 8,
        "angular_velocity_covariance": [float(v) for v in gyr.ravel()],
        "linear_acceleration_covariance": [float(v) for v in acc.ravel()],
        "update_rate": rate,
        "noise_resolved": {"gyr": ok_g, "acc": ok_a},
        "calibration": {
            "convention": CONVENTION,
            "acc": {"bias": [float(v) for v in calibration["acc"].bias],
                    "matrix": matrix_list(calibration["acc"].matrix), "unit": "m/s^2"},
            "gyr": {"bias": [float(v) for v in calibration["gyr"].bias],
                    "matrix": matrix_list(calibration["gyr"].matrix), "unit": "rad/s"},
        },
    }  # fmt: skip
