"""Uncertainty carried from step 1 (S', o) through step 2 (the alignment T_R) to the calibration.

Step 2 fits ``T_R`` to step 1's output ``S'(r - o)`` on the rotation3d phases, so an error of
step 1 moves ``alpha``: :func:`alignment_sensitivity` measures ``d alpha / d (S', o)`` by
refitting the alignment with step 1's parameters moved by small steps (forward differences,
the same fit as the stage runs), and :func:`imucal.uncertainty.two_step_covariance` combines it with
step 1's covariance and the alignment's own.

Assumptions (docs/uncertainty.md): step 1 and step 2 use independent noise (the magnetometer's
ellipsoid fit and its alignment share the rotation3d samples; their correlation is left out);
first order in the errors.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np

from imucal import errormodel
from imucal.fits.alignment import AlignmentResult
from imucal.uncertainty import propagate, upper_entries, upper_matrix

#: Relative step of the forward differences of the alignment refits.
SENSITIVITY_STEP = 1e-5


def alignment_sensitivity(
    align: Callable[[dict], AlignmentResult],
    raw_phases: Mapping[str, np.ndarray],
    upper: np.ndarray,
    bias: np.ndarray,
) -> np.ndarray:
    """``d alpha / d (S' upper entries row by row, o)`` of a step-2 fit, shape (3, 9).

    Parameters
    ----------
    align : callable
        Phase label -> step-1 output (n_i, 3) to :class:`AlignmentResult`; the stage's own
        alignment (method, exact form).
    raw_phases : dict of str to ndarray, shape (n_i, 3)
        The sensor's readings in each phase, as the stage fits them (e.g. low-pass filtered).
    upper : ndarray, shape (3, 3)
        Step 1's ``S'``.
    bias : ndarray, shape (3,)
        Step 1's ``o``.
    """
    phases = {k: np.asarray(v, dtype=float) for k, v in raw_phases.items()}

    def alpha_of(theta: np.ndarray) -> np.ndarray:
        u, o = upper_matrix(theta[:6]), theta[6:]
        return align({k: errormodel.apply(u, o, v) for k, v in phases.items()}).alpha_rad

    theta = np.concatenate([upper_entries(upper), np.asarray(bias, dtype=float)])
    # forward differences: one refit per parameter (the alignment is linear in step 1's output
    # to well below the step, so central ones would only double the cost)
    alpha = alpha_of(theta)
    jac = np.empty((3, theta.size))
    for i in range(theta.size):
        h = SENSITIVITY_STEP * max(1.0, abs(theta[i]))
        step = np.zeros_like(theta)
        step[i] = h
        jac[:, i] = (alpha_of(theta + step) - alpha) / h
    return jac


def upper_bias_covariance(matrix: np.ndarray, covariance: np.ndarray) -> np.ndarray:
    """Covariance of ``(S' upper entries, o)`` from that of ``(K row-major, o)``, shape (9, 9).

    ``S'`` is the upper-triangular factor of ``K`` (QR with a positive diagonal), as the rate
    table's step 1 takes it.
    """
    k = np.asarray(matrix, dtype=float)

    def upper_and_bias(p: np.ndarray) -> np.ndarray:
        _, u = errormodel.upper_triangular_factor(p[:9].reshape(3, 3))
        return np.concatenate([upper_entries(u), p[9:]])

    x = np.concatenate([k.ravel(), np.zeros(3)])
    return propagate(upper_and_bias, x, np.asarray(covariance, dtype=float))
