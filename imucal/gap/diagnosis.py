"""The diagnosis of a full-protocol session: localise, attribute, measure the shrinkage.

``diagnose`` runs the session through the in-process pipeline, builds its twin, renders the
null replicas and hands them to :func:`imucal.gap.scoring.scored_diagnosis`, which scores every
location, attributes the gap and assembles ``diagnosis.json`` with its ``verdict``; to that
``diagnose`` adds the detail the report needs and ``noted``: effects present that open no gap
with this pipeline (large misalignment under the exact rotation), with ``misalignment``.

A session whose calibration chain stops on its data (too few positions, a fit the samples do not
support), or whose twin cannot be replicated, still gets a diagnosis: the static diagnosis of
its ``static`` recording (:func:`imucal.gap.composite.diagnose_partial_session`, its twin's noise
white as the full protocol's, so that a wandering bias stays an effect), with the reason in
``fallback``; readings clipped at a sensor's range are then ``noted`` as ``saturation``
(with the fraction per sensor), since clipping shows in the readings without a twin.
"""

from __future__ import annotations

import time
from collections.abc import Mapping

import pandas as pd

from imucal.gap.blocks import StaticBlocks, decimate_static_table, window_segments
from imucal.gap.clipping import note_saturation
from imucal.gap.library import library
from imucal.gap.locations import clip_fractions
from imucal.gap.misalignment import misalignment_report
from imucal.gap.null import run_replicas
from imucal.gap.scoring import DiagnosisSettings, scored_diagnosis
from imucal.gap.statistics import HALVES, PROTOCOL_STATISTICS, compute_statistics
from imucal.gap.twin import build_twin
from imucal.pipeline.full import PipelineOptions, calibrate_session


def diagnose(
    imu: Mapping[str, pd.DataFrame],
    reference: pd.DataFrame | None,
    options: PipelineOptions,
    *,
    dataset: str,
    segments: pd.DataFrame | None = None,
    settings: DiagnosisSettings = DiagnosisSettings(),
    static_blocks: StaticBlocks | None = None,
) -> dict:
    """Diagnose the sim-to-real gap of one session.

    Parameters
    ----------
    imu : dict of str to DataFrame
        Ingested IMU recordings (SI). A ``static`` recording longer than
        :data:`imucal.gap.blocks.STATIC_WINDOW_S` is cut into its window and block means
        (:func:`imucal.gap.blocks.decimate_static`), unless ``static_blocks`` is given.
    reference : DataFrame or None
        Ingested reference.
    options : PipelineOptions
    dataset : str
    segments : DataFrame, optional
        The workflow's segments table (automatic segmentation when None); the static
        recording's rows are cut to its window.
    settings : DiagnosisSettings
    static_blocks : StaticBlocks, optional
        The block means of the static recording when ``imu['static']`` is already its window
        (:func:`imucal.gap.blocks.read_decimated_static` reads both from the file batch by
        batch, so that a long recording is never held whole).

    Returns
    -------
    dict
        diagnosis.json (see the module docstring); extra keys: ``twin``, ``null``,
        ``all_locations``, ``timing_s``, ``settings``.
    """
    t0 = time.perf_counter()
    imu = dict(imu)
    if static_blocks is None and "static" in imu:
        imu["static"], static_blocks = decimate_static_table(imu["static"])
    if static_blocks is not None and segments is not None:
        segments = window_segments(segments, imu["static"])
    fit = None
    try:
        fit = calibrate_session(imu, reference, options, segments)
        fit.extra["static_blocks"] = static_blocks
        stats = {h: compute_statistics(fit, h) for h in HALVES}
        twin = build_twin(fit, fit.extra["options"])
        reps = run_replicas(twin, settings.replicas, settings.seed)
    except ValueError as err:
        from imucal.gap.composite import diagnose_partial_session

        where = (
            "the session's twin cannot be replicated" if fit else "the calibration chain stopped"
        )
        # the full protocol's twin: white noise, a wandering bias is an effect
        result = diagnose_partial_session(
            imu.get("static"), dataset=dataset,
            calibration=fit.calibration.to_dict() if fit else None,
            sensitivity=options.sensitivity, gravity_m_s2=options.gravity_m_s2, settings=settings,
            wander=False,
        )  # fmt: skip
        result["fallback"] = f"{where} ({err}); the static recording alone is diagnosed"
        # clipping is seen in the readings themselves, with or without a twin
        return note_saturation(result, clip_fractions(imu, options))
    t_null = time.perf_counter()
    models = library(settings.exclude)
    result = scored_diagnosis(
        twin, fit, stats, reps, models, dataset=dataset, settings=settings, own_evidence=True
    )
    misalignment = (
        misalignment_report(fit, [r.session for r in reps], settings.detect_z)
        if "large_misalignment" in models
        else None
    )
    return {
        **result,
        "noted": ["large_misalignment"] if misalignment and misalignment["present"] else [],
        "misalignment": misalignment,
        "twin": twin.describe(),
        "pipeline_notes": list(fit.extra.get("notes", [])),
        "held_by_hand": list(fit.extra["options"].held_by_hand),
        "settings": {
            **settings.describe(),
            "statistics": {k: v.unit for k, v in PROTOCOL_STATISTICS.items()},
        },
        "timing_s": {
            "null": t_null - t0,
            "total": time.perf_counter() - t0,
        },
    }
