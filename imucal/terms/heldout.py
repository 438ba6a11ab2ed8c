"""Held-out improvement of each term against the shrink the diagnosis predicted for its effect.

Every estimator scores its term on data the term was not fitted on (leave-one-out segments for
the temperature polynomials and the g-sensitivity, half the rate levels predicted from the
other half for the lever arm); :func:`heldout_comparison` turns the held-out RMS without and
with the term into the achieved shrink ``1 - MS_with / MS_without`` of the mean square and
sets it beside the diagnosis's ``heldout_shrink`` of the effect behind the term.

The two are not the same measure: the diagnosis's shrink is that of its gap, a sum of squared
scores *less what noise alone gives*, while ``MS_with`` still holds the noise of the held-out
residuals. The achieved raw shrink is therefore a lower bound of the achieved shrink of the
excess, and the comparison is one-sided: the term falls short of the prediction when the
prediction exceeds the achieved shrink by more than three of its standard deviations. The
standard deviation is that of the ratio of two mean squares over ``n`` held-out values of
roughly Gaussian residuals, ``rho sqrt(2 / n + 2 / n)`` (the two treated as independent: when
the effect dominates the residual without the term, they are nearly so; otherwise the
standard deviation is an overestimate).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from scipy.spatial.transform import Rotation

from imucal.calibration import ImuCalibration
from imucal.columns import ACC, GYR, SI_COLUMN_UNITS, TIME
from imucal.gap import session as st
from imucal.modelterms.registry import term_class
from imucal.pipeline.full import SessionFit
from imucal.pipeline.stages import apply_calibration
from imucal.segments.table import row_bounds

#: The held-out residual of the gyroscope's terms that no estimator fits on.
POSE_TO_POSE = (
    "gravity direction pose to pose: each rotation3d rest's up direction predicted from the "
    "previous rest's through the gyro integrated between them (rad)"
)


def pose_to_pose_angles(fit: SessionFit, calibration: ImuCalibration) -> np.ndarray:
    """Angles (rad) between each rotation3d rest's measured up direction and the one predicted
    from the previous rest through the gyroscope integrated from the end of that rest to the
    start of this one, shape (rests - 1,); empty without a rotation3d recording.

    Held out for the gyroscope's terms: they are fitted on resting means, never on the
    platform's turns. ``calibration`` calibrates the recording with its whole model.
    """
    if "rotation3d" not in fit.imu:
        return np.zeros(0)
    table = fit.imu["rotation3d"]
    values, _ = apply_calibration(
        table, {"units": SI_COLUMN_UNITS}, calibration, source="rotation3d"
    )
    gyr, acc = values[list(GYR)].to_numpy(float), values[list(ACC)].to_numpy(float)
    t = table[TIME].to_numpy(float)
    rows = st.segment_rows(fit, "rotation3d", "static")
    rests = list(row_bounds(rows))
    up = st.segment_means(acc, rows)
    up /= np.linalg.norm(up, axis=1, keepdims=True)
    angles = []
    for (_, end), (start, _), u0, u1 in zip(rests[:-1], rests[1:], up[:-1], up[1:], strict=True):
        sl = slice(end - 1, start + 1)
        q = st.integrate_orientation(t[sl], gyr[sl], np.array([0.0, 0.0, 0.0, 1.0]))[-1]
        predicted = Rotation.from_quat(q).inv().apply(u0)
        angles.append(np.arccos(np.clip(predicted @ u1, -1.0, 1.0)))
    return np.asarray(angles)


def pose_to_pose_comparison(
    fit: SessionFit, base: ImuCalibration, with_term: ImuCalibration
) -> dict:
    """The pose-to-pose gravity residual (:func:`pose_to_pose_angles`) of the calibration
    without terms and of the one with them, as :func:`heldout_comparison` reports a term's (no
    prediction: the diagnosis has none for this residual); ``note`` when the session has fewer
    than 3 rotation3d rests."""
    without = pose_to_pose_angles(fit, base)
    if len(without) < 2 or not np.all(np.isfinite(without)):
        return {"residual": POSE_TO_POSE, "note": "fewer than 3 rotation3d rests"}
    with_ = pose_to_pose_angles(fit, with_term)
    rms = [float(np.sqrt(np.mean(a**2))) for a in (without, with_)]
    achieved, std = _achieved(*rms, len(without))
    return {"residual": POSE_TO_POSE, "rms_without": rms[0], "rms_with": rms[1],
            "values": len(without), "achieved_shrink": achieved, "achieved_std": std,
            "predicted_shrink": None, "short_of_prediction": None}  # fmt: skip


def _achieved(rms_without: float, rms_with: float, n: int) -> tuple[float, float]:
    rho = (rms_with / rms_without) ** 2 if rms_without > 0 else float("nan")
    return 1.0 - rho, rho * float(np.sqrt(4.0 / max(n, 1)))


def heldout_comparison(term: str, evidence: Mapping, diagnosis: Mapping | None) -> dict:
    """The achieved held-out shrink of ``term`` beside the diagnosis's prediction.

    Parameters
    ----------
    term : str
        A registered term's name; its class reads the evidence
        (:meth:`~imucal.modelterms.contract.ModelTerm.heldout_rms`) and says what was held out
        (:attr:`~imucal.modelterms.contract.ModelTerm.heldout_residual`).
    evidence : dict
        The term's evidence from its estimator.
    diagnosis : dict or None
        diagnosis.json of the session.

    Returns
    -------
    dict
        ``residual`` (what was held out), ``rms_without``, ``rms_with``, ``values``,
        ``achieved_shrink`` and ``achieved_std``, ``predicted_shrink`` (None when the diagnosis
        has none for the effect), ``short_of_prediction`` (None without a prediction), or
        ``note`` when the term has no held-out residual.
    """
    cls = term_class(term)
    pair = cls.heldout_rms(evidence)
    if pair is None:
        return {"note": f"no held-out residual of {term} in this session"}
    without, with_, n = pair
    achieved, std = _achieved(without, with_, n)
    effects = {e["name"]: e for e in (diagnosis or {}).get("effects", [])}
    predicted = effects.get(cls.effect, {}).get("heldout_shrink")
    return {
        "residual": cls.heldout_residual,
        "rms_without": without,
        "rms_with": with_,
        "values": n,
        "achieved_shrink": achieved,
        "achieved_std": std,
        "predicted_shrink": predicted,
        "short_of_prediction": None if predicted is None else bool(predicted > achieved + 3 * std),
    }
