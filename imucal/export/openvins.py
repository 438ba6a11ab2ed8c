"""OpenVINS: ``kalibr_imu_chain.yaml`` with the noise values and the IMU intrinsics.

Conventions, from OpenVINS's source (rpng/open_vins):

* ``docs/propagation-analytical.dox`` ("IMU Intrinsic Models"):
  ``w_I = R_GYROtoIMU D_w (w_m - T_g a_I - b_g)``, ``a_I = R_ACCtoIMU D_a (a_m - b_a)``,
  ``D_w = T_w^-1``, ``D_a = T_a^-1``.
* ``ov_msckf/src/core/VioManagerOptions.h``: reads ``Tw``, ``Ta``, ``R_IMUtoACC``,
  ``R_IMUtoGYRO``, ``Tg`` under ``imu0``; ``Dw = Tw^-1``, ``R_GYROtoIMU = R_IMUtoGYRO^T``;
  with ``model: "kalibr"`` it keeps only the LOWER triangle of ``Dw`` and ``Da`` (6 values each).
  ``ov_msckf/src/state/Propagator.cpp`` applies ``R_ACCtoIMU`` in every model.
* ``config/*/kalibr_imu_chain.yaml``: the file layout (``imu0`` with ``T_i_b``, the four noise
  densities, ``rostopic``, ``time_offset``, ``update_rate``, ``model``, the five matrices).

Ours is ``v_B = K (v_m - b)``. With the IMU frame I = B: ``K = R_XtoIMU D`` with ``D`` lower
triangular (rotation times lower), so ``T = D^-1`` (lower) and ``R_IMUtoX = R_XtoIMU^T``.
Our g-sensitivity (``w_B = K (w_m - b) - G a_B``, :mod:`imucal.modelterms`) is
``K_g T_g a_I``: ``T_g = K_g^-1 G`` (zero when the model has none). OpenVINS estimates the biases; ours are given as
``imucal_acc_bias`` and ``imucal_gyr_bias`` for initial values (keys OpenVINS does not read).
The header is ``%YAML 1.0`` and a document start: OpenCV's YAML reader (which OpenVINS uses)
accepts ``%YAML:1.`` and ``%YAML 1.``, PyYAML only the second.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from imucal.calibration import SensorCalibration
from imucal.export.kalibr import kalibr_imu
from imucal.export.model import ROSTOPIC, NoiseParameters, matrix_list, rotation_times_lower

MODEL = "kalibr"
#: First lines of the file (a YAML 1.0 directive both OpenCV and PyYAML read).
DIRECTIVE = "%YAML 1.0\n---\n"


def openvins_intrinsics(
    calibration: Mapping[str, SensorCalibration], g_sensitivity: np.ndarray | None = None
) -> dict:
    """``Tw``, ``R_IMUtoGYRO``, ``Ta``, ``R_IMUtoACC``, ``Tg`` of our calibration (I = B);
    ``g_sensitivity`` is our ``G`` (3, 3; rad/s per m/s^2, frame B), None for none."""
    g = np.zeros((3, 3)) if g_sensitivity is None else np.asarray(g_sensitivity, dtype=float)
    r_gyr_to_imu, d_w = rotation_times_lower(calibration["gyr"].matrix)
    r_acc_to_imu, d_a = rotation_times_lower(calibration["acc"].matrix)
    return {
        "Tw": np.linalg.inv(d_w),
        "R_IMUtoGYRO": r_gyr_to_imu.T,
        "Ta": np.linalg.inv(d_a),
        "R_IMUtoACC": r_acc_to_imu.T,
        "Tg": np.linalg.solve(calibration["gyr"].matrix, g),
    }


def openvins_imu_chain(
    calibration: Mapping[str, SensorCalibration],
    noise: NoiseParameters,
    *,
    g_sensitivity: np.ndarray | None = None,
    rostopic: str = ROSTOPIC,
) -> dict:
    """The ``imu0`` entry of OpenVINS's ``kalibr_imu_chain.yaml`` (``g_sensitivity``: our
    ``G``, see :func:`openvins_intrinsics`)."""
    intrinsics = openvins_intrinsics(calibration, g_sensitivity)
    imu0 = {
        "T_i_b": matrix_list(np.eye(4)),
        **kalibr_imu(noise, rostopic=rostopic),  # OpenVINS reads Kalibr's noise keys
        "time_offset": 0.0,
        "model": MODEL,
        **{name: matrix_list(m) for name, m in intrinsics.items()},
        "imucal_acc_bias": [float(v) for v in calibration["acc"].bias],
        "imucal_gyr_bias": [float(v) for v in calibration["gyr"].bias],
    }
    return {"imu0": imu0}
