"""The gap diagnosis of a partial session by its scope: which parts it scores
(:func:`imucal.gap.composite.partial_scope`, the one choice the workflow's inputs read too) and
the diagnosis of that scope, with the clipping seen in the readings themselves.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import pandas as pd

from imucal.gap.clipping import ingest_clip_fractions, note_saturation
from imucal.gap.composite import diagnose_partial_session, diagnose_rests_scope, partial_scope
from imucal.gap.motion import reference_part
from imucal.gap.poses import diagnose_poses
from imucal.gap.scoring import DiagnosisSettings

if TYPE_CHECKING:
    from imucal.io.dataset import Dataset


def session_scope(info: Dataset, poses_recording: str | None) -> str:
    """The scope of a partial session's diagnosis from its ``dataset.yaml``
    (:func:`imucal.gap.composite.partial_scope`).

    Parameters
    ----------
    info : Dataset
    poses_recording : str or None
        The recording of its static poses with a temperature channel
        (:func:`imucal.terms.poseholdout.holdout_recording`), None without one.
    """
    return partial_scope(
        static="static" in info.recordings,
        references=bool(info.orientation_references),
        poses=poses_recording is not None,
    )


def diagnose_partial(
    info: Dataset,
    tables: Mapping[str, pd.DataFrame],
    *,
    dataset: str,
    calibration: Mapping,
    summary: Mapping,
    segments: pd.DataFrame | None,
    references: Mapping[str, tuple[pd.DataFrame, Mapping]],
    settings: DiagnosisSettings,
    windows_s: Sequence[float],
    poses_recording: str | None,
    settle_s: float,
) -> dict:
    """The gap diagnosis of a partial session on the parts its scope scores
    (:func:`session_scope`).

    Parameters
    ----------
    info : Dataset
        The session's ``dataset.yaml`` (its recordings, references, sensitivity, gravity).
    tables : mapping of str to DataFrame
        The ingested recordings of its scope, named as the rule's inputs name them: ``static``
        (the static recording), ``moving_<recording>`` (a recording with an orientation
        reference), ``poses`` (the static poses), ``rest_<recording>`` (every recording, whose
        rests are scored).
    dataset : str
        The dataset's name.
    calibration : mapping
        Its ``partial/calibration.json``.
    summary : mapping
        The ingest's ``summary.json`` (the clipped samples of every recording).
    segments : DataFrame or None
        Its segments table (None for the scope ``static``, which does not read it).
    references : mapping
        Recording -> (ingested orientation reference, its metadata), for the scopes with a
        reference.
    settings : DiagnosisSettings
    windows_s : sequence of float
        The windows of the motion statistics (config ``reference.windows_s``), s.
    poses_recording : str or None
        As in :func:`session_scope`.
    settle_s : float
        The settling time left out at the start of a pose (config
        ``temperature_holdout.settle_s``), s.

    Returns
    -------
    dict
        diagnosis.json of the scope (:func:`~imucal.gap.composite.diagnose_partial_session`,
        :func:`~imucal.gap.composite.diagnose_rests_scope` or
        :func:`~imucal.gap.poses.diagnose_poses`), with ``saturation`` noted where a sensor's
        readings clip (:func:`~imucal.gap.clipping.note_saturation`), whatever the scope can
        replay.
    """
    scope = session_scope(info, poses_recording)
    common = dict(
        dataset=dataset,
        calibration=calibration,
        sensitivity=info.sensitivity,
        gravity_m_s2=info.gravity_m_s2,
        settings=settings,
    )
    motion = not_scored = None
    if "reference" in scope:
        motion, not_scored = reference_part(
            tables={name: tables[f"moving_{name}"] for name in references},
            references=references,
            calibration=calibration,
            segments=segments,
            where={name: info.reference_where(name) for name in references},
            sensitivity=info.sensitivity,
            gravity_m_s2=info.gravity_m_s2,
            windows_s=windows_s,
        )
    if scope == "poses":  # static poses with a temperature channel, no static recording
        result = diagnose_poses(
            tables["poses"], segments, recording=poses_recording, settle_s=settle_s, **common
        )
    elif scope == "rests":  # the longest rest as the static recording, else the short ones pooled
        rests = {k.removeprefix("rest_"): t for k, t in tables.items() if k.startswith("rest_")}
        result = diagnose_rests_scope(rests, segments, **common)
    else:
        static = tables["static"] if "static" in scope else None
        result = diagnose_partial_session(
            static, motion=motion, reference_not_scored=not_scored, **common
        )
    return note_saturation(result, ingest_clip_fractions(summary))
