"""The gyroscope's g-sensitivity matrix from resting segments (frame B)."""

from __future__ import annotations

import numpy as np

from imucal.gap import session as st
from imucal.gap.temperature import heldout_residuals, select_model
from imucal.modelterms.gsensitivity import GSensitivity
from imucal.pipeline.full import SessionFit


def fit_g_sensitivity(fit: SessionFit) -> tuple[GSensitivity | None, dict]:
    """``G`` of ``w_B = c + G a_B`` over the session's resting segments (calibrated means).

    Each gyro axis is regressed on the three components of the calibrated specific force with
    a constant (the bias left by the fit) and, where the resting segments have a temperature
    reading that changes, the temperature: a drift per axis over poses taken at different
    temperatures is the competing explanation of orientation-dependent gyro means, and the
    two are decided in one regression. The term is included only when the joint model
    predicts held-out segments better than the model without ``G``
    (:func:`imucal.gap.temperature.select_model`: leave-one-out residuals, the
    one-standard-error rule). The standard deviations are those of least squares.

    Parameters
    ----------
    fit : SessionFit

    Returns
    -------
    term : GSensitivity or None
        None when the resting segments do not span three directions of gravity, or when the
        held-out comparison prefers the model without ``G`` (refused).
    evidence : dict
        ``heldout_rms`` (``without``, ``with``, rad/s), ``segments``, ``temperature`` (whether
        the temperature is in both models), or ``refused``.
    """
    rest = st.resting_means(fit, None)
    w, f, temp = rest.gyr, rest.acc, rest.temp
    ok = np.all(np.isfinite(w), axis=1) & np.all(np.isfinite(f), axis=1)
    w, f, temp = w[ok], f[ok], temp[ok]
    x0 = np.ones((len(w), 1))
    with_temp = bool(np.all(np.isfinite(temp)) and len(temp) and np.ptp(temp) > 0)
    if with_temp:
        x0 = np.column_stack([x0, temp - temp.mean()])
    x1 = np.column_stack([x0, f])
    p = x0.shape[1]
    if len(w) < 8 + p or np.linalg.matrix_rank(x1) < 3 + p:
        return None, {"refused": "the resting segments do not span three gravity directions"}
    coef, *_ = np.linalg.lstsq(x1, w, rcond=None)
    dof = len(w) - x1.shape[1]
    sigma2 = np.sum((w - x1 @ coef) ** 2, axis=0) / dof
    var = np.diag(np.linalg.pinv(x1.T @ x1))[p:]
    std = np.sqrt(np.outer(sigma2, var))
    before, after = (np.sqrt(np.mean(heldout_residuals(x, w) ** 2)) for x in (x0, x1))
    chosen, _ = select_model({"without": x0, "with": x1}, w)
    evidence = {
        "heldout_rms": {"without": float(before), "with": float(after)},
        "unit": "rad/s",
        "segments": len(w),
        "temperature": with_temp,
    }
    if chosen == "without":
        refused = (
            "the model with G does not predict held-out resting segments better than the one "
            f"without (leave-one-out RMS {after:.3g} vs {before:.3g} rad/s"
            + (", the temperature in both)" if with_temp else ")")
        )
        return None, {**evidence, "refused": refused}
    method = "resting calibrated gyro means against calibrated specific force, with a constant"
    if with_temp:
        method += " and the temperature"
    return GSensitivity(coef[p:].T, std, method), evidence
