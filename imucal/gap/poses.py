"""The gap diagnosis of a session of static poses: its longest pose as a static recording.

A recording of a motionless IMU left in a few static poses for hours each (a thermal
experiment: :mod:`imucal.terms.poseholdout`) has neither a ``static`` recording nor an
orientation reference, the two parts the diagnosis of a partial session scores
(:mod:`imucal.gap.composite`). Yet each pose *is* a static recording: one orientation, the
sensor at rest, the temperature channel beside it. So the longest declared pose, its first
``settle_s`` left out (the handling's transient), is diagnosed as the session's static part,
with the static twin, locations and library (:mod:`imucal.gap.static`); the scope is ``poses``
(``poses+reference`` beside recordings with a reference). The other poses repeat it at other
orientations: a static twin renders one orientation, so they are not concatenated into it
(the jumps between poses would read as a trend and a bias wander).
"""

from __future__ import annotations

from collections.abc import Mapping

import pandas as pd

from imucal.columns import POSE_KINDS, TIME
from imucal.gap.composite import diagnose_partial_session
from imucal.gap.motionstats import MotionRecording
from imucal.gap.motiontwin import MotionTwin
from imucal.gap.scoring import DiagnosisSettings
from imucal.segments.table import rows_of


def longest_pose(
    table: pd.DataFrame, segments: pd.DataFrame, *, recording: str, settle_s: float
) -> tuple[pd.DataFrame, dict]:
    """The samples of the longest static pose of a recording, from ``settle_s`` after its start.

    Parameters
    ----------
    table : DataFrame
        The ingested recording.
    segments : DataFrame
        The session's segments table (its ``position`` / ``static`` rows of ``recording``).
    recording : str
    settle_s : float
        Time left out at the start of the pose (s).

    Returns
    -------
    pose : DataFrame
        Its rows of ``table`` (index reset).
    info : dict
        ``recording``, ``label``, ``start_s``, ``end_s`` (of the part used), ``poses`` (how
        many were declared), ``settle_s``.

    Raises
    ------
    ValueError
        If the recording has no static pose.
    """
    rows = rows_of(segments, recording, *POSE_KINDS)
    if rows.empty:
        raise ValueError(f"recording {recording!r} has no static pose in the segments table")
    longest = rows.loc[(rows["end_s"] - rows["start_s"]).idxmax()]
    part = table.iloc[int(longest["start_index"]) : int(longest["end_index"])]
    t = part[TIME].to_numpy(dtype=float)
    part = part[t >= t[0] + settle_s].reset_index(drop=True)
    t_used = part[TIME].to_numpy(dtype=float)
    info = {
        "recording": recording,
        "label": str(longest["label"]),
        "start_s": float(t_used[0]) if len(t_used) else float("nan"),
        "end_s": float(t_used[-1]) if len(t_used) else float("nan"),
        "poses": int(len(rows)),
        "settle_s": float(settle_s),
    }
    return part, info


def diagnose_poses(
    table: pd.DataFrame,
    segments: pd.DataFrame,
    *,
    recording: str,
    settle_s: float,
    motion: tuple[Mapping[str, MotionRecording], MotionTwin] | None = None,
    reference_not_scored: str | None = None,
    dataset: str,
    calibration: Mapping | None,
    sensitivity: Mapping[str, float],
    gravity_m_s2: float,
    settings: DiagnosisSettings,
) -> dict:
    """The gap diagnosis of a session of static poses (module docstring).

    Parameters
    ----------
    table, segments, recording, settle_s
        As in :func:`longest_pose`.
    motion, reference_not_scored, dataset, calibration, sensitivity, gravity_m_s2, settings
        As in :func:`imucal.gap.composite.diagnose_partial_session`.

    Returns
    -------
    dict
        The diagnosis of :func:`~imucal.gap.composite.diagnose_partial_session` with the pose
        as its static recording, ``scope`` ``poses`` or ``poses+reference`` (``none`` with the
        reason when nothing could be scored) and ``pose`` (:func:`longest_pose`'s info).
    """
    pose, info = longest_pose(table, segments, recording=recording, settle_s=settle_s)
    result = diagnose_partial_session(
        pose, motion=motion, reference_not_scored=reference_not_scored, dataset=dataset,
        calibration=calibration, sensitivity=sensitivity, gravity_m_s2=gravity_m_s2,
        settings=settings,
    )  # fmt: skip
    scope = {"static": "poses", "static+reference": "poses+reference"}.get(result["scope"])
    if scope is None:
        return {**result, "pose": info}
    return {**result, "scope": scope, "pose": info}
