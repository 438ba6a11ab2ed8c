"""The diagnosis of one session: localise, attribute, measure the shrinkage (diagnosis.json).

``diagnose`` runs the session through the in-process pipeline, builds its twin, renders the
null replicas, scores every location, attributes the gap forward and assembles
``diagnosis.json`` (``format_version``, ``dataset``, ``gap``, ``locations``, ``effects``,
``explained``, ``remaining``) plus the detail the report needs, and ``noted``: effects present that open no gap
with this pipeline (large misalignment under the exact rotation), with ``misalignment``.

A session whose calibration chain stops on its data (too few positions, a fit the samples do not
support), or whose twin cannot be replicated, still gets a diagnosis: the static diagnosis of
its ``static`` recording (:func:`imucal.gap.partial.diagnose_partial_session`), with the reason
in ``fallback``; readings clipped at a sensor's range are then ``noted`` as ``saturation``
(with the fraction per sensor), since clipping shows in the readings without a twin.
"""

from __future__ import annotations

import time
from collections.abc import Mapping

import numpy as np
import pandas as pd

from imucal.gap.attribution import attribute, confusable
from imucal.gap.effects import library, misalignment_report
from imucal.gap.null import build_null, holm, run_replicas
from imucal.gap.statistics import CATALOGUE, HALVES, clip_fractions, compute_statistics
from imucal.gap.twin import build_twin
from imucal.pipeline.full import PipelineOptions, calibrate_session

FORMAT_VERSION = 1
LOCATION_FIELDS = ("stage", "sensor", "axis", "segment", "statistic")


def _locations(keys, t, reject, only_significant: bool) -> list[dict]:
    out = []
    for k, z, r in zip(keys, t, reject, strict=True):
        if not np.isfinite(z) or (only_significant and not r):
            continue
        out.append({**dict(zip(LOCATION_FIELDS, k, strict=True)), "z": float(z), "in_gap": bool(r)})
    return sorted(out, key=lambda d: -abs(d["z"]))


def diagnose(
    imu: Mapping[str, pd.DataFrame],
    reference: pd.DataFrame | None,
    options: PipelineOptions,
    *,
    dataset: str,
    segments: pd.DataFrame | None = None,
    replicas: int = 20,
    alpha: float = 0.05,
    seed: int = 1000,
    min_heldout_shrink: float = 0.3,
    crn_seeds: int = 3,
    detect_z: float = 4.0,
    exclude: tuple = (),
) -> dict:
    """Diagnose the sim-to-real gap of one session.

    Parameters
    ----------
    imu : dict of str to DataFrame
        Ingested IMU recordings (SI).
    reference : DataFrame or None
        Ingested reference.
    options : PipelineOptions
    dataset : str
    segments : DataFrame, optional
        The workflow's segments table (automatic segmentation when None).
    replicas : int
        Twin replicas in the null (>= 5).
    alpha : float
        Family-wise level of the location test (Holm).
    seed : int
        First replica seed.
    min_heldout_shrink : float
        Smallest held-out shrink (0..1) for an effect to be accepted.
    crn_seeds : int
        Replica seeds an effect is rendered with to measure its shift of the statistics.
    detect_z : float
        Smallest |score| of an effect's estimate against the null for it to be evaluated.
    exclude : tuple of str
        Effects left out of the library (the unknown-effect check).

    Returns
    -------
    dict
        diagnosis.json (see the module docstring); extra keys: ``twin``, ``null``,
        ``all_locations``, ``timing_s``, ``settings``.
    """
    t0 = time.perf_counter()
    fit = None
    try:
        fit = calibrate_session(imu, reference, options, segments)
        stats = {h: compute_statistics(fit, h) for h in HALVES}
        twin = build_twin(fit, fit.extra["options"])
        reps = run_replicas(twin, replicas, seed)
    except ValueError as err:
        from imucal.gap.partial import diagnose_partial_session

        where = (
            "the session's twin cannot be replicated" if fit else "the calibration chain stopped"
        )
        result = diagnose_partial_session(
            imu.get("static"), dataset=dataset,
            calibration=fit.calibration.to_dict() if fit else None,
            sensitivity=options.sensitivity, gravity_m_s2=options.gravity_m_s2,
            replicas=replicas, alpha=alpha, seed=seed, min_heldout_shrink=min_heldout_shrink,
            crn_seeds=crn_seeds, detect_z=detect_z,
        )  # fmt: skip
        result["fallback"] = f"{where} ({err}); the static recording alone is diagnosed"
        # clipping is seen in the readings themselves, with or without a twin
        clipped = {s: f for s, f in clip_fractions(imu, options).items() if f > 0}
        if clipped:
            result["noted"] = ["saturation"]
            result["saturation"] = {"clip_fraction": clipped}
        return result
    t_null = time.perf_counter()
    null_full = build_null(reps, None)
    null_b = build_null(reps, "B")
    t_real = null_full.t(stats[None])
    p = null_full.p_values(t_real)
    reject = holm(p, alpha)
    gap_before = null_full.gap(stats[None])
    loo = null_full.leave_one_out_gaps()
    p95 = float(np.percentile(loo, 95))
    significant = bool(reject.any())
    models = library(exclude)
    cands, explained, shift, _, rounds = attribute(
        twin, fit, stats, reps, null_full, null_b, models,
        alpha=alpha, min_heldout_shrink=min_heldout_shrink, n_seeds=crn_seeds, detect_z=detect_z,
    )  # fmt: skip
    misalignment = (
        misalignment_report(fit, [r.fit for r in reps], detect_z)
        if "large_misalignment" in models
        else None
    )
    t_after = null_full.t(stats[None], shift)
    reject_after = holm(null_full.p_values(t_after), alpha)
    effects = []
    for c in sorted(cands, key=lambda c: (not c.accepted, -(c.heldout_shrink or -1e9))):
        effects.append({
            "name": c.name,
            "params": c.params,
            "gap_before": c.gap_before,
            "gap_after": c.gap_after,
            "shrink": c.shrink,
            "heldout_shrink": c.heldout_shrink,
            "heldout_deviance": c.heldout_deviance,
            "accepted": c.accepted,
            "detect": None if not np.isfinite(c.detect) else float(c.detect),
            "detect_z": None if not np.isfinite(c.detect_z) else float(c.detect_z),
            "evaluated": c.evaluated,
            "signature_hits": [
                dict(zip(LOCATION_FIELDS, k, strict=True))
                for k, r in zip(null_full.keys, reject, strict=True)
                if r and models[c.name].matches(k)
            ],
            "note": c.note,
        })  # fmt: skip
    return {
        "format_version": FORMAT_VERSION,
        "dataset": dataset,
        "gap": {"total": gap_before, "null_p95": p95, "significant": significant},
        "locations": _locations(null_full.keys, t_real, reject, True),
        "effects": effects,
        "explained": explained,
        "remaining": {
            "total": null_full.gap(stats[None], shift),
            "significant": bool(reject_after.any()),
            "locations": _locations(null_full.keys, t_after, reject_after, True),
        },
        "confusable": confusable(rounds, explained, min_heldout_shrink),
        "noted": ["large_misalignment"] if misalignment and misalignment["present"] else [],
        "misalignment": misalignment,
        "all_locations": _locations(null_full.keys, t_real, reject, False),
        "null": {
            "replicas": replicas,
            "alpha": alpha,
            "n_locations": len(null_full.keys),
            "loo_gap_median": float(np.median(loo)),
            "loo_false_alarm": float(np.mean(null_full.leave_one_out_flags(alpha))),
        },  # fmt: skip
        "twin": twin.describe(),
        "pipeline_notes": list(fit.extra.get("notes", [])),
        "held_by_hand": list(fit.extra["options"].held_by_hand),
        "settings": {
            "seed": seed,
            "min_heldout_shrink": min_heldout_shrink,
            "crn_seeds": crn_seeds,
            "detect_z": detect_z,
            "exclude": list(exclude),
            "statistics": {k: v.unit for k, v in CATALOGUE.items()},
        },  # fmt: skip
        "timing_s": {
            "null": t_null - t0,
            "total": time.perf_counter() - t0,
        },
    }
