"""The sensor error model of Zhang et al. (2014), eqs. 1-11 and 15-16.

A tri-axial sensor reading ``r`` (SI units, sensor frame S) maps to the module frame B as

    calibrated = T_R @ T_N @ S @ (r - o)  =  matrix @ (r - o)

with the bias ``o`` (eq. 1), the diagonal scale ``S`` (eq. 2), the upper-triangular
non-orthogonality ``T_N`` (eq. 6) and the rotation ``T_R`` from S to B (eq. 5, exact form eqs. 7-10).
``S' = T_N S`` is upper triangular, so any calibration matrix factors uniquely (QR with a positive
diagonal) into a rotation times ``S'``; "matrix + bias" is the complete description and
(scale, xi, alpha) is its decomposition.

The rotation is parameterised by the rotation vector ``alpha`` (rad). The paper's small-angle form
(eq. 5) is available with ``exact=False``; it is not a rotation and is only accurate to first order.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation


def rotation_matrix(alpha_rad: np.ndarray, exact: bool = True) -> np.ndarray:
    """Rotation ``T_R`` from the sensor frame S to the module frame B.

    Parameters
    ----------
    alpha_rad : array_like, shape (3,)
        Rotation vector (alpha_x, alpha_y, alpha_z) in rad.
    exact : bool
        True for the exact rotation (exponential map); False for the paper's small-angle
        matrix of eq. 5, ``I + [alpha]_x``.

    Returns
    -------
    ndarray, shape (3, 3)
    """
    alpha = np.asarray(alpha_rad, dtype=float).reshape(3)
    if exact:
        return Rotation.from_rotvec(alpha).as_matrix()
    ax, ay, az = alpha
    # eq. 5
    return np.array([[1.0, -az, ay], [az, 1.0, -ax], [-ay, ax, 1.0]])


def nonorthogonality_matrix(xi_rad: np.ndarray) -> np.ndarray:
    """Non-orthogonality ``T_N`` of eq. 6 for angles ``xi_rad`` (xi_x, xi_y, xi_z), shape (3,)."""
    xx, xy, xz = np.asarray(xi_rad, dtype=float).reshape(3)
    return np.array([[1.0, xz, -xy], [0.0, 1.0, xx], [0.0, 0.0, 1.0]])


def compose(
    scale: np.ndarray, xi_rad: np.ndarray, alpha_rad: np.ndarray, exact: bool = True
) -> np.ndarray:
    """Calibration matrix ``T_R T_N S`` (eqs. 4, 11, 16), shape (3, 3)."""
    shape = nonorthogonality_matrix(xi_rad) @ np.diag(np.asarray(scale, dtype=float).reshape(3))
    return rotation_matrix(alpha_rad, exact) @ shape


@dataclass(frozen=True)
class Decomposition:
    """Scale, non-orthogonality and rotation of a calibration matrix.

    Attributes
    ----------
    scale : ndarray, shape (3,)
        Diagonal of ``S`` (dimensionless, output unit per input unit).
    xi_rad : ndarray, shape (3,)
        Non-orthogonality angles of ``T_N`` (eq. 6), rad.
    alpha_rad : ndarray, shape (3,)
        Rotation vector of ``T_R``, rad.
    """

    scale: np.ndarray
    xi_rad: np.ndarray
    alpha_rad: np.ndarray


def upper_triangular_factor(matrix: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Factor ``matrix = Q @ U`` with Q a proper rotation and U upper triangular, diag(U) > 0.

    Parameters
    ----------
    matrix : array_like, shape (3, 3)
        Must have a positive determinant (a calibration never mirrors the axes).

    Returns
    -------
    rotation : ndarray, shape (3, 3)
    upper : ndarray, shape (3, 3)

    Raises
    ------
    ValueError
        If the matrix is singular or mirrors (determinant <= 0).
    """
    m = np.asarray(matrix, dtype=float)
    det = np.linalg.det(m)
    if not np.isfinite(det) or det <= 0:
        raise ValueError(
            f"calibration matrix must have a positive determinant, got {det:.3g}: {m.tolist()}"
        )
    q, u = np.linalg.qr(m)
    signs = np.sign(np.diag(u))
    return q * signs, signs[:, None] * u


def decompose(matrix: np.ndarray) -> Decomposition:
    """Invert :func:`compose` (exact rotation) for a matrix with positive determinant."""
    rotation, upper = upper_triangular_factor(matrix)
    scale = np.diag(upper).copy()
    # upper = T_N S: row 0 = (sx, xi_z sy, -xi_y sz), row 1 = (0, sy, xi_x sz)  (eq. 6)
    xi = np.array([upper[1, 2] / scale[2], -upper[0, 2] / scale[2], upper[0, 1] / scale[1]])
    alpha = Rotation.from_matrix(rotation).as_rotvec()
    return Decomposition(scale=scale, xi_rad=xi, alpha_rad=alpha)


def apply(matrix: np.ndarray, bias: np.ndarray, readings: np.ndarray) -> np.ndarray:
    """Calibrate readings: ``matrix @ (reading - bias)`` row by row (eq. 11).

    Parameters
    ----------
    matrix : array_like, shape (3, 3)
    bias : array_like, shape (3,)
        In the unit of the readings.
    readings : array_like, shape (n, 3)

    Returns
    -------
    ndarray, shape (n, 3)
    """
    r = np.asarray(readings, dtype=float)
    return (r - np.asarray(bias, dtype=float)) @ np.asarray(matrix, dtype=float).T


def invert(matrix: np.ndarray, bias: np.ndarray, calibrated: np.ndarray) -> np.ndarray:
    """Readings that calibrate to ``calibrated`` (shape (n, 3)): ``inv(matrix) @ c + bias``."""
    c = np.asarray(calibrated, dtype=float)
    return np.linalg.solve(np.asarray(matrix, dtype=float), c.T).T + np.asarray(bias, dtype=float)
