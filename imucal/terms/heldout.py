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

from imucal.terms.selection import EFFECT_OF_TERM

#: What the held-out residual of each term is (for terms.json and the report).
RESIDUAL_OF_TERM = {
    "temperature": "|a| - g of resting means, rate-table runs left out, each predicted from the "
    "others (m/s^2)",
    "g_sensitivity": "resting calibrated gyro means, each predicted from the others (rad/s)",
    "lever_arm": "rate-table run means of the acc at half the rate levels, predicted from the "
    "other half (m/s^2)",
}


def _achieved(rms_without: float, rms_with: float, n: int) -> tuple[float, float]:
    rho = (rms_with / rms_without) ** 2 if rms_without > 0 else float("nan")
    return 1.0 - rho, rho * float(np.sqrt(4.0 / max(n, 1)))


def _rms_pair(term: str, evidence: Mapping) -> tuple[float, float, int] | None:
    """Held-out RMS without and with the term, and the number of held-out values."""
    if term == "temperature":
        acc = evidence.get("acc", {})
        if "heldout_rms" not in acc or "refused" in acc:
            return None
        rms = acc["heldout_rms"]
        return rms[acc["without"]], rms[acc["with"]], int(acc["segments"])
    rms = evidence.get("heldout_rms")
    if not rms:
        return None
    n = rms.get("values", evidence.get("segments", 0))
    return rms["without"], rms["with"], int(n)


def heldout_comparison(term: str, evidence: Mapping, diagnosis: Mapping | None) -> dict:
    """The achieved held-out shrink of ``term`` beside the diagnosis's prediction.

    Parameters
    ----------
    term : str
        One of :data:`imucal.modelterms.TERMS`.
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
    pair = _rms_pair(term, evidence) if term in RESIDUAL_OF_TERM else None
    if pair is None:
        return {"note": f"no held-out residual of {term} in this session"}
    without, with_, n = pair
    achieved, std = _achieved(without, with_, n)
    effects = {e["name"]: e for e in (diagnosis or {}).get("effects", [])}
    predicted = effects.get(EFFECT_OF_TERM[term], {}).get("heldout_shrink")
    return {
        "residual": RESIDUAL_OF_TERM[term],
        "rms_without": without,
        "rms_with": with_,
        "values": n,
        "achieved_shrink": achieved,
        "achieved_std": std,
        "predicted_shrink": predicted,
        "short_of_prediction": None if predicted is None else bool(predicted > achieved + 3 * std),
    }
