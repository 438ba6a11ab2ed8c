"""The gyroscope's g-sensitivity matrix from resting segments (frame B)."""

from __future__ import annotations

import numpy as np

from imucal.gap import statistics as st
from imucal.modelterms import GSensitivity
from imucal.pipeline.full import SessionFit
from imucal.terms.temperature import heldout_residuals


def fit_g_sensitivity(fit: SessionFit) -> tuple[GSensitivity | None, dict]:
    """``G`` of ``w_B = c + G a_B`` over the session's resting segments (calibrated means).

    Each gyro axis is regressed on the three components of the calibrated specific force with
    a constant (the bias left by the fit); the standard deviations are those of least squares.
    Held-out evidence: the leave-one-out RMS of the resting gyro means with and without ``G``.

    Parameters
    ----------
    fit : SessionFit

    Returns
    -------
    term : GSensitivity or None
        None when the resting segments do not span three directions of gravity (refused).
    evidence : dict
        ``heldout_rms`` (``without``, ``with``, rad/s), ``segments``, or ``refused``.
    """
    rest = st.resting_means(fit, None)
    w, f = rest.gyr, rest.acc
    ok = np.all(np.isfinite(w), axis=1) & np.all(np.isfinite(f), axis=1)
    w, f = w[ok], f[ok]
    x0 = np.ones((len(w), 1))
    x1 = np.column_stack([x0, f])
    if len(w) < 8 or np.linalg.matrix_rank(x1) < 4:
        return None, {"refused": "the resting segments do not span three gravity directions"}
    coef, *_ = np.linalg.lstsq(x1, w, rcond=None)
    dof = len(w) - 4
    sigma2 = np.sum((w - x1 @ coef) ** 2, axis=0) / dof
    var = np.diag(np.linalg.pinv(x1.T @ x1))[1:]
    std = np.sqrt(np.outer(sigma2, var))
    before, after = (np.sqrt(np.mean(heldout_residuals(x, w) ** 2)) for x in (x0, x1))
    evidence = {
        "heldout_rms": {"without": float(before), "with": float(after)},
        "unit": "rad/s",
        "segments": len(w),
    }
    method = "resting calibrated gyro means against calibrated specific force, with a constant"
    return GSensitivity(coef[1:].T, std, method), evidence
