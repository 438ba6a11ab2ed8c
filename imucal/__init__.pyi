from .calibration import FORMAT_VERSION, ImuCalibration, SensorCalibration
from .errormodel import (
    Decomposition,
    apply,
    compose,
    decompose,
    invert,
    nonorthogonality_matrix,
    rotation_matrix,
    upper_triangular_factor,
)
