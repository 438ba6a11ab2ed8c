"""Exports of a calibration and its noise to the tools users feed: Kalibr
(:mod:`imucal.export.kalibr`), OpenVINS (:mod:`imucal.export.openvins`) and the ROS
``sensor_msgs/Imu`` covariances (:mod:`imucal.export.ros`); :func:`export_files` renders the files
of one format. Conventions and their sources: ``docs/exports.md``."""

from imucal.export.files import FORMATS, export_files
from imucal.export.kalibr import kalibr_imu, kalibr_imu_chain, kalibr_intrinsics
from imucal.export.model import (
    NoiseParameters,
    inertial_calibration,
    lower_times_rotation,
    noise_parameters,
    rotation_times_lower,
)
from imucal.export.openvins import openvins_imu_chain, openvins_intrinsics
from imucal.export.ros import ros_imu_covariances, sample_covariance

__all__ = [
    "FORMATS",
    "NoiseParameters",
    "export_files",
    "inertial_calibration",
    "kalibr_imu",
    "kalibr_imu_chain",
    "kalibr_intrinsics",
    "lower_times_rotation",
    "noise_parameters",
    "openvins_imu_chain",
    "openvins_intrinsics",
    "ros_imu_covariances",
    "rotation_times_lower",
    "sample_covariance",
]
