from .files import export_files
from .formats import FORMATS
from .kalibr import kalibr_imu, kalibr_imu_chain, kalibr_intrinsics
from .model import (
    NoiseParameters,
    inertial_calibration,
    lower_times_rotation,
    noise_parameters,
    rotation_times_lower,
)
from .openvins import openvins_imu_chain, openvins_intrinsics
from .ros import ros_imu_covariances, sample_covariance
