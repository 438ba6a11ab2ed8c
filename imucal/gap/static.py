"""The sim-to-real gap of a session off the paper's protocol, on what its static recording shows.

A partial session (:mod:`imucal.pipeline.partial`) has no cube, rate table or reference, so the
full-protocol diagnosis (:func:`imucal.gap.diagnosis.diagnose`) cannot refit it. What such a
session usually does have is a long ``static`` recording, and that is where this diagnosis
looks, with the definitions of :mod:`imucal.gap`: the twin is
:class:`~imucal.gap.statictwin.StaticTwin`, the locations are those of :mod:`imucal.gap.streams`, the
null, scores, attribution and ``diagnosis.json`` are :func:`imucal.gap.scoring.scored_diagnosis`
as for a full session.

The effects a static recording can show are the specs' models of scope ``static``
(:func:`imucal.gap.library.scope_library`: ``timing_jitter``, host receive latency;
``bias_instability``, Allan excess; ``temperature_drift``, biases following the temperature
channel), each estimator reading the recording's streams; the others are listed with the
reason (:func:`imucal.gap.library.not_observable`).
"""

from __future__ import annotations

import time
from collections.abc import Mapping

import pandas as pd

from imucal.constants import STANDARD_GRAVITY_M_S2
from imucal.gap.library import not_observable, scope_library
from imucal.gap.scoring import FORMAT_VERSION, DiagnosisSettings, scope_diagnosis
from imucal.gap.statictwin import build_static_twin
from imucal.gap.statistics import HALVES
from imucal.gap.streams import split_streams, static_statistics


def unscored_diagnosis(dataset: str, reason: str) -> dict:
    """diagnosis.json of a session where no location can be scored, saying why."""
    return {
        "format_version": FORMAT_VERSION,
        "dataset": dataset,
        "gap": {"total": None, "null_p95": None, "significant": False},
        "locations": [],
        "effects": [],
        "explained": [],
        "remaining": {"total": None, "significant": False, "locations": []},
        "scope": "none",
        "reason": reason,
        "confusable": [],
        "all_locations": [],
        "null": {},
    }


def diagnose_static(
    table: pd.DataFrame,
    *,
    dataset: str,
    calibration: Mapping | None = None,
    sensitivity: Mapping[str, float] | None = None,
    gravity_m_s2: float = STANDARD_GRAVITY_M_S2,
    settings: DiagnosisSettings = DiagnosisSettings(),
    wander: bool = True,
) -> dict:
    """The gap diagnosis of a partial session from its static recording.

    Parameters
    ----------
    table : DataFrame
        The ingested ``static`` recording (rows in receive order, SI).
    dataset : str
    calibration : dict, optional
        The session's calibration JSON (``partial/calibration.json``).
    sensitivity : dict, optional
        SI per count per sensor from dataset.yaml (estimated from the data where absent).
    gravity_m_s2 : float
    settings : DiagnosisSettings
        As for a full session; ``exclude`` leaves effects out of the static scope's library.
    wander : bool
        As :func:`~imucal.gap.statictwin.build_static_twin` (False: the twin's noise is white
        and a wandering bias is the effect ``bias_instability``).

    Returns
    -------
    dict
        diagnosis.json (:func:`~imucal.gap.scoring.scored_diagnosis`) plus ``scope``,
        ``not_observable``, ``twin``, ``settings``, ``timing_s``.

    Raises
    ------
    ValueError
        If the recording has no stream of 100 rows.
    """
    t0 = time.perf_counter()
    streams = split_streams(table)
    if not streams:
        raise ValueError(
            "the static recording has no acc/gyro or magnetometer stream of >= 100 rows"
        )
    stats = {h: static_statistics(streams, h) for h in HALVES}
    twin = build_static_twin(streams, calibration, dict(sensitivity or {}), gravity_m_s2, wander)
    return scope_diagnosis(
        twin, streams, stats, scope_library("static"), scope="static",
        not_observable=not_observable("static"),
        cannot_show="the session cannot show this effect (no such stream or channel)",
        dataset=dataset, settings=settings, started=t0,
    )  # fmt: skip
