"""imucal: calibration of 9-axis IMUs on a 3-D rotation platform (Zhang et al., 2014).

The import package is ``imucal``; the distribution is ``imu-platform-cal`` (the PyPI name
``imucal`` belongs to an unrelated project by mad-lab-fau).
"""

from importlib.metadata import PackageNotFoundError, version

from imucal.calibration import FORMAT_VERSION, ImuCalibration, SensorCalibration
from imucal.errormodel import (
    Decomposition,
    apply,
    compose,
    decompose,
    invert,
    nonorthogonality_matrix,
    rotation_matrix,
    upper_triangular_factor,
)

try:
    __version__ = version("imu-platform-cal")
except PackageNotFoundError:  # running from a source tree that was not installed
    __version__ = "0+unknown"

__all__ = [
    "FORMAT_VERSION",
    "Decomposition",
    "ImuCalibration",
    "SensorCalibration",
    "apply",
    "compose",
    "decompose",
    "invert",
    "nonorthogonality_matrix",
    "rotation_matrix",
    "upper_triangular_factor",
    "__version__",
]
