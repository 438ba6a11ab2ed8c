"""The sim-to-real gap of recordings with an orientation reference (motion capture, robot).

A recording declared with an orientation reference shows what a static recording cannot: the
gyroscope over the rates and orientations the hand or the robot gave it, against an independent
measure of the same rotation.

The locations and the estimators of the effects are in :mod:`imucal.gap.motionstats`, the twin
that replays the recording's motion in :mod:`imucal.gap.motiontwin`; this module prepares such
recordings and their twin for the diagnosis (:func:`motion_part`, :func:`reference_part`).

The effects such a recording can show are the specs' models of scope ``motion``
(:func:`imucal.gap.library.scope_library`): ``g_sensitivity`` (a gyroscope output following the
specific force), ``scale_nonlinearity`` (a response curved in the rate, which makes a scale
fitted on fast motion wrong on slow motion) and ``reference_jitter`` (the reference's samples
taken off their time stamps: an error growing with the rate), and the disturbances of hand-held
and robot use with their own locations (``world_magnetic`` in :mod:`imucal.gap.worldfield`,
``shock`` and ``vibration`` in :mod:`imucal.gap.disturbance`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd

from imucal.gap.motionstats import WINDOWS_S, MotionRecording
from imucal.gap.motiontwin import MotionTwin, build_motion_twin, recorded_motion
from imucal.segments.table import rows_of


def motion_part(
    tables: Mapping[str, pd.DataFrame],
    references: Mapping[str, tuple[pd.DataFrame, Mapping]],
    calibration: Mapping | None,
    segments: pd.DataFrame,
    where: Mapping[str, str],
    sensitivity: Mapping[str, float],
    gravity_m_s2: float,
    windows_s: Sequence[float] = WINDOWS_S,
) -> tuple[dict[str, MotionRecording], MotionTwin]:
    """The recordings with an orientation reference and their twin, for the diagnosis.

    Parameters
    ----------
    tables, references, calibration, where
        As in :func:`recorded_motion`.
    segments : DataFrame
        The segments table; ``static`` and ``position`` segments are the rests (noise).
    sensitivity, gravity_m_s2, windows_s
        As in :func:`build_motion_twin`.

    Returns
    -------
    recordings : dict of str to MotionRecording
        The recordings whose reference could be aligned (the others are named in the twin's
        notes with the reason), with the twin's gyroscope full scale.
    twin : MotionTwin

    Raises
    ------
    ValueError
        When no recording's reference can be aligned (each reason in the message).
    """
    recordings, skipped = {}, []
    for name in references:
        try:
            recordings |= recorded_motion(tables, {name: references[name]}, calibration, where)
        except ValueError as err:  # a reference the gyroscope cannot be aligned with
            skipped.append(f"{name}: {err}")
    if not recordings:
        raise ValueError(
            "no recording's reference could be aligned with its gyroscope: " + "; ".join(skipped)
        )
    rests = {}
    for name, rec in recordings.items():
        rows = rows_of(segments, name, "static", "position")
        mask = np.zeros(len(rec.t_s), dtype=bool)
        for lo, hi in zip(rows["start_s"].astype(float), rows["end_s"].astype(float)):
            mask |= (rec.t_s >= lo) & (rec.t_s <= hi)
        rests[name] = mask
    twin = build_motion_twin(
        recordings, tables, calibration, rests, sensitivity, gravity_m_s2, windows_s
    )
    notes = [f"not scored, the reference could not be aligned: {why}" for why in skipped]
    recordings = {
        name: dataclasses.replace(rec, gyr_full_scale_rad_s=twin.gyr_full_scale_rad_s)
        for name, rec in recordings.items()
    }
    return recordings, dataclasses.replace(twin, notes=[*twin.notes, *notes])


def reference_part(**inputs) -> tuple[tuple | None, str | None]:
    """:func:`motion_part` of the same keyword arguments, or why the recordings with a reference
    cannot be scored.

    Returns
    -------
    part : (dict of str to MotionRecording, MotionTwin) or None
    not_scored : str or None
        The reason when ``part`` is None (no reference could be aligned with its gyroscope).
    """
    try:
        return motion_part(**inputs), None
    except ValueError as err:
        return None, str(err)
