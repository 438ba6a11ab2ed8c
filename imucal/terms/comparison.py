"""The closed loop's two-sided check: the gap the diagnosis predicted for the session with its
explained effects modelled, against what remains once the terms are in the calibration."""

from __future__ import annotations

from collections.abc import Mapping

from imucal.modelterms.registry import term_class


def gap_comparison(before: Mapping, after: Mapping, in_model: list) -> dict | None:
    """The gap the diagnosis predicted for the session with its explained effects modelled,
    beside what remains of the gap of the session recalibrated with the terms: the same
    statistic, so the comparison is two-sided.

    The prediction is ``remaining.total`` of the diagnosis before (its twin with the
    explained effects added). The achieved value is ``remaining.total`` of the diagnosis after:
    the terms in the calibration, and in its twin the effects it still explains, those
    without a term (a bias instability, a timing jitter). Whether a significant gap is left is
    each diagnosis's own test against its null; when neither has one they agree, when one has
    and the other not that decides, and when both have they agree if the totals differ by less
    than the larger ``null_p95`` of the two (the 95th percentile of the total when there is no
    gap: the statistic's own noise). An effect that the diagnosis after still
    explains although a term in the model stands for it means the term did not take it: the
    verdict is then short of the prediction whatever the totals.

    Parameters
    ----------
    before, after : dict
        diagnosis.json of the session and of the session with the terms (gap/after.json).
    in_model : list of str
        The terms in the model.

    Returns
    -------
    dict or None
        ``before``, ``predicted``, ``achieved``, ``tolerance``, ``still_explained`` (effects
        the diagnosis after explains) and ``verdict`` ('as predicted', 'better than
        predicted' or 'short of the prediction', with the term that did not take its effect);
        None when either diagnosis lacks the numbers.
    """
    try:
        total = float(before["gap"]["total"])
        predicted = float(before["remaining"]["total"])
        achieved = float(after["remaining"]["total"])
        left = {"predicted": bool(before["remaining"]["significant"]),
                "achieved": bool(after["remaining"]["significant"])}  # fmt: skip
        tolerance = max(float(before["gap"]["null_p95"]), float(after["gap"]["null_p95"]))
    except (KeyError, TypeError):
        return None
    still = list(after.get("explained", []))
    untaken = [t for t in in_model if term_class(t).effect in still]
    if untaken:
        verdict = f"short of the prediction: the diagnosis after still explains the effect of {', '.join(untaken)}"
    elif left["achieved"] != left["predicted"]:
        # one side has a significant gap left, the other none: the diagnoses' own test decides
        verdict = "short of the prediction" if left["achieved"] else "better than predicted"
    elif not left["achieved"]:
        verdict = "as predicted: no significant gap left"
    elif achieved > predicted + tolerance:
        verdict = "short of the prediction"
    elif achieved < predicted - tolerance:
        verdict = "better than predicted"
    else:
        verdict = "as predicted"
    return {"before": total, "predicted": predicted, "achieved": achieved,
            "tolerance": tolerance, "still_explained": still, "verdict": verdict}  # fmt: skip
