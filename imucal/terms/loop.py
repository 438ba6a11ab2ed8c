"""The closed loop: the effects a diagnosis accepts become terms of the calibration model.

:func:`close_loop` decides per term (:mod:`imucal.terms.selection`), estimates the included
ones on the session calibrated with the paper's model, corrects the session's readings with
them (every sample mapped to the terms' reference: ``reading' = o + K^-1 v`` with ``v`` the
calibrated value of the whole model and ``(K, o)`` the paper's calibration the terms were
estimated against), and recalibrates the corrected session with the paper's chain, so that
bias and matrices hold at the reference. The corrected session is what the diagnosis after
the loop is run on (:func:`imucal.gap.diagnose`): the gap before and after in one report.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd

from imucal import errormodel
from imucal.calibration import ImuCalibration
from imucal.columns import SENSOR_COLUMNS, SENSORS, SI_COLUMN_UNITS
from imucal.io import to_jsonable
from imucal.modelterms import ModelTerms, term_class, term_names
from imucal.pipeline.full import PipelineOptions, SessionFit, calibrate_session
from imucal.pipeline.graph import unaffected
from imucal.pipeline.stages import apply_calibration
from imucal.terms.estimators import estimator_of
from imucal.terms.heldout import heldout_comparison, pose_to_pose_comparison
from imucal.terms.selection import TermSettings, decide


def corrected_session(
    imu: Mapping[str, pd.DataFrame], base: ImuCalibration, terms: ModelTerms
) -> dict[str, pd.DataFrame]:
    """The recordings with the terms taken out of their readings (same rows and columns).

    Parameters
    ----------
    imu : dict of str to DataFrame
        Ingested recordings (SI).
    base : ImuCalibration
        The calibration the terms were estimated against (its own terms ignored).
    terms : ModelTerms

    Returns
    -------
    dict of str to DataFrame
        Readings ``o + K^-1 v`` per sensor, ``v`` calibrated with ``base`` and ``terms``; a
        sensor whose calibrated values the terms leave as they are keeps its readings to the
        bit (:func:`changed_sensors`).
    """
    model = base.with_terms(terms)
    metadata = {"units": SI_COLUMN_UNITS}
    out = {}
    for name, table in imu.items():
        values, _ = apply_calibration(table, metadata, model, source=name)
        paper, _ = apply_calibration(table, metadata, base.with_terms(ModelTerms()), source=name)
        fixed = table.copy()
        for s in SENSORS:
            cal = base.sensor(s)
            cols = list(SENSOR_COLUMNS[s])
            v = values[cols].to_numpy(float)
            if not np.array_equal(v, paper[cols].to_numpy(float), equal_nan=True):
                fixed[cols] = errormodel.invert(cal.matrix, cal.bias, v)
        out[name] = fixed
    return out


def changed_sensors(imu: Mapping[str, pd.DataFrame], corrected: Mapping[str, pd.DataFrame]) -> set:
    """The sensors whose readings differ between two versions of a session's recordings."""
    return {
        s
        for s in SENSORS
        for name, table in imu.items()
        if not np.array_equal(
            table[list(SENSOR_COLUMNS[s])].to_numpy(float),
            corrected[name][list(SENSOR_COLUMNS[s])].to_numpy(float),
            equal_nan=True,
        )
    }


def recalibrate(
    base: SessionFit, corrected: Mapping[str, pd.DataFrame], options: PipelineOptions
) -> SessionFit:
    """The paper's chain on the corrected session, the stages whose readings the correction did
    not change taken from the session's fit as they are (:func:`imucal.pipeline.graph.
    unaffected`)."""
    done = unaffected(
        base.extra["records"], changed_sensors(base.imu, corrected), frozenset(corrected)
    )
    return calibrate_session(corrected, base.reference, options, base.segments, done=done)


def close_loop(
    imu: Mapping[str, pd.DataFrame],
    reference: pd.DataFrame | None,
    options: PipelineOptions,
    *,
    segments: pd.DataFrame,
    diagnosis: Mapping | None,
    settings: TermSettings,
    fits: Mapping[str, Mapping] | None = None,
) -> dict:
    """Decide, estimate and fold the optional terms into a session's calibration.

    Parameters
    ----------
    imu : dict of str to DataFrame
        Ingested recordings (SI).
    reference : DataFrame or None
    options : PipelineOptions
    segments : DataFrame
        The session's segments table.
    diagnosis : dict or None
        The session's diagnosis.json (for 'auto').
    settings : TermSettings
    fits : dict of str to dict, optional
        The session's own stage artifacts (the workflow's rules', by stage name): the terms
        are estimated against them instead of a second run of the chain
        (:func:`imucal.pipeline.full.calibrate_session` ``done``).

    Returns
    -------
    dict
        ``terms``: term -> ``setting``, ``included`` (bool), ``reason``, ``evidence``, and for
        a term in the model ``heldout`` (achieved held-out shrink beside the diagnosis's
        prediction, :func:`imucal.terms.heldout.heldout_comparison`);
        ``calibration``: the recalibrated :class:`ImuCalibration` with its terms, or None when
        no term is included (the paper's calibration stands); ``corrected``: the corrected
        recordings (None likewise); with terms, ``pose_to_pose``: the held-out gravity
        direction pose to pose of the paper's model against the whole model
        (:func:`imucal.terms.heldout.pose_to_pose_comparison`).
    """
    record = {}
    for term in term_names():
        wanted, reason = decide(term, settings, diagnosis)
        record[term] = {"setting": settings.switch(term), "included": wanted, "reason": reason}
    if not any(r["included"] for r in record.values()):
        return {"terms": record, "calibration": None, "corrected": None}
    try:
        found, base = _estimate(imu, reference, options, segments, record, settings, fits)
        for term in found:
            record[term]["heldout"] = heldout_comparison(term, record[term]["evidence"], diagnosis)
        for term, r in record.items():
            if r["included"] and term not in found:
                r["included"] = False
                refused = _refusals(r.get("evidence", {}))
                r["reason"] += f"; refused: {refused}"
        if not found:
            return {"terms": record, "calibration": None, "corrected": None}
        terms = ModelTerms(**found)
        corrected = corrected_session(imu, base.calibration, terms)
        refit = recalibrate(base, corrected, options)
        model = refit.calibration.with_terms(terms)
        pose_to_pose = pose_to_pose_comparison(base, base.calibration, model)
    except ValueError as err:
        # the data do not carry the paper's chain or a term's estimate through (degenerate
        # motion, a stage that cannot run in process): the paper's calibration stands
        for r in record.values():
            if r["included"]:
                r["included"] = False
                r["reason"] += f"; could not be estimated on these data: {err}"
        return {"terms": record, "calibration": None, "corrected": None}
    return {
        "terms": record,
        "calibration": model,
        "corrected": corrected,
        "pose_to_pose": pose_to_pose,
    }


def _estimate(imu, reference, options, segments, record: dict, settings: TermSettings, fits):
    """The included terms' estimates (term -> value) and the paper's fit they are against
    (the session's own ``fits`` where given); each term's evidence goes into ``record``."""
    fit = base = calibrate_session(imu, reference, options, segments, done=fits)
    found: dict = {}
    for name, r in record.items():
        if not r["included"]:
            continue
        value, r["evidence"] = estimator_of(name)(fit, **settings.options.get(name, {}))
        if value is None:
            continue
        found[name] = value
        if term_class(name).refits_session:
            # the later terms are estimated on the session without this term's effect
            fixed = corrected_session(imu, base.calibration, ModelTerms(**found))
            fit = recalibrate(base, fixed, options)
    return found, base


def _refusals(evidence: Mapping) -> str:
    """The refusal reasons in an evidence record (nested per sensor)."""
    found = [evidence["refused"]] if "refused" in evidence else []
    found += [
        f"{k}: {v['refused']}"
        for k, v in evidence.items()
        if isinstance(v, Mapping) and "refused" in v
    ]
    return "; ".join(found) or "nothing to estimate"


def terms_summary(result: Mapping) -> dict:
    """terms.json: the decisions with their evidence, the terms in the model and the
    recalibrated calibration (None when no term is in the model), JSON-ready."""
    cal = result["calibration"]
    return {
        "format_version": 1,
        "in_model": cal.terms.names() if cal is not None else [],
        "terms": to_jsonable(result["terms"]),
        "heldout_pose_to_pose": to_jsonable(result.get("pose_to_pose")),
        "calibration": cal.to_dict() if cal is not None else None,
    }


def diagnosis_after(
    result: Mapping,
    reference: pd.DataFrame | None,
    options: PipelineOptions,
    *,
    dataset: str,
    segments: pd.DataFrame,
    settings,
) -> dict:
    """The diagnosis of the session recalibrated with the terms in the model
    (:func:`imucal.gap.diagnose` on the corrected recordings); without a term, a record
    saying that the diagnosis before is the calibration's."""
    if result["corrected"] is None:
        return {
            "format_version": 1,
            "dataset": dataset,
            "in_model": [],
            "note": "no model term is in the calibration: the diagnosis is that of the paper's model",
        }
    from imucal.gap.diagnosis import diagnose

    after = diagnose(
        result["corrected"], reference, options, dataset=dataset, segments=segments,
        settings=settings,
    )  # fmt: skip
    return {**after, "in_model": result["calibration"].terms.names()}
