"""The gap diagnosis of a partial session, from its parts: a static recording and recordings with
an orientation reference.

A partial session (:mod:`imucal.pipeline.partial`) has no cube, rate table or MT Manager
reference, so the full-protocol diagnosis cannot refit it; it may hold a static recording (:class:`imucal.gap.statictwin.StaticTwin`) and
recordings with an orientation reference (:class:`imucal.gap.motiontwin.MotionTwin`). Their
locations differ (stages ``static``/``temperature`` and ``reference``), so one diagnosis scores
them together (:func:`diagnose_partial_session`): a replica of the composite is a replica of each part with the same seed, its
statistics the union of theirs. An effect is rendered in the part whose library holds it (the
part whose locations can show it), and its estimator reads that part of the session.

Which parts a partial session is scored on is decided in one place, :func:`partial_scope`,
for the workflow's inputs and for the diagnosis alike. A session with neither part nor declared
static poses is scored on its rests (:func:`diagnose_rests_scope`): its longest rest as its
static recording when the rest is long enough for the static statistics
(:func:`rest_as_static`), else its shorter rests pooled (:mod:`imucal.gap.rests`), else, for a
magnetometer turned without any rest, the residual of its field fit (:mod:`imucal.gap.fieldfit`).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Mapping
from dataclasses import dataclass

import pandas as pd

from imucal.gap.effects import EffectModel
from imucal.gap.fieldfit import diagnose_field_fit, field_fit_part
from imucal.gap.library import not_observable, scope_library
from imucal.gap.motionstats import MotionRecording, motion_statistics
from imucal.gap.motiontwin import MotionTwin
from imucal.gap.rests import diagnose_rests, session_rests
from imucal.gap.scoring import DiagnosisSettings, scope_diagnosis
from imucal.gap.static import diagnose_static, unscored_diagnosis
from imucal.gap.statictwin import build_static_twin
from imucal.gap.statistics import HALVES
from imucal.gap.streams import split_streams, static_statistics
from imucal.gap.twin import Replica
from imucal.segments.table import rows_of

#: Shortest rest scored in place of a static recording (s): each half of it must hold twice the
#: 10 s averaging time of the Allan statistic (:func:`imucal.gap.streams.noise_statistics`).
MIN_REST_S = 40.0


@dataclass(frozen=True)
class CompositeTwin:
    """Twins of the parts of one session.

    Attributes
    ----------
    parts : dict
        Part name -> twin (anything with ``replica(seed, effects, halves)`` and ``describe()``).
    libraries : dict
        Part name -> names of the effects rendered in that part.
    """

    parts: dict
    libraries: dict

    def describe(self) -> dict:
        return {name: twin.describe() for name, twin in self.parts.items()}

    def replica(self, seed: int, effects: tuple = (), halves: tuple = HALVES) -> Replica:
        """One replica of every part with ``seed``; each part renders its own effects."""
        sessions: dict = {}
        stats: dict = {h: {} for h in halves}
        for name, twin in self.parts.items():
            own = tuple(e for e in effects if e.name in self.libraries[name])
            rep = twin.replica(seed, own, halves)
            sessions[name] = rep.session
            for h in halves:
                stats[h].update(rep.stats[h])
        return Replica(seed, sessions, stats)


def on_part(model: EffectModel, part: str) -> EffectModel:
    """The same effect model, its estimator reading one part of a composite session."""
    estimate = model.estimate

    def on(session: Mapping, half):
        return estimate(session[part], half)

    return dataclasses.replace(model, estimate=on)


def composite_library(libraries: Mapping[str, Mapping[str, EffectModel]]) -> dict:
    """Part -> effect library into one library whose estimators read their part."""
    out = {}
    for part, library in libraries.items():
        for name, model in library.items():
            out[name] = on_part(model, part)
    return out


def rest_as_static(
    tables: Mapping[str, pd.DataFrame], segments: pd.DataFrame, min_duration_s: float = MIN_REST_S
) -> tuple[pd.DataFrame | None, str]:
    """The longest rest of a session's recordings, as a static recording.

    Parameters
    ----------
    tables : mapping of str to DataFrame
        Ingested recordings by name.
    segments : DataFrame
        The segments table; its ``static`` and ``position`` rows are the rests.
    min_duration_s : float
        Shortest rest that is scored (s).

    Returns
    -------
    table : DataFrame or None
        The rows of the longest rest (None when no rest is long enough).
    source : str
        Which rest it is, or why none is scored.
    """
    best = None
    for name, table in tables.items():
        for row in rows_of(segments, name, "static", "position").itertuples():
            duration = float(row.end_s) - float(row.start_s)
            if best is None or duration > best[0]:
                best = (duration, name, row)
    if best is None or best[0] < min_duration_s:
        need = (
            f"a rest is scored from {min_duration_s:g} s (each half twice the 10 s averaging "
            "time of the static statistics)"
        )
        if best is None:
            return None, f"no rest was found; {need}"
        return None, f"the longest rest is {best[0]:.1f} s; {need}"
    duration, name, row = best
    table = tables[name]
    t = table["t_s"].to_numpy(dtype=float)
    part = table[(t >= float(row.start_s)) & (t <= float(row.end_s))].reset_index(drop=True)
    return part, f"the rest {row.label} of recording {name} ({duration:.1f} s)"


def partial_scope(*, static: bool, references: bool, poses: bool) -> str:
    """Which parts of a partial session its gap diagnosis scores: the one choice that the
    workflow's inputs and the diagnosis both read.

    Parameters
    ----------
    static : bool
        The session has a ``static`` recording.
    references : bool
        It declares recordings with an orientation reference.
    poses : bool
        It declares static poses on a recording with a temperature channel
        (:func:`imucal.terms.poseholdout.holdout_recording` is not None).

    Returns
    -------
    str
        ``static+reference`` or ``reference`` with recordings with a reference (with or
        without the static recording); ``static`` with a static recording alone; ``poses``
        for the poses (:mod:`imucal.gap.poses`); else ``rests``: the rests the segmentation
        finds in its recordings (:func:`diagnose_rests_scope`).
    """
    if references:
        return "static+reference" if static else "reference"
    if static:
        return "static"
    return "poses" if poses else "rests"


def diagnose_rests_scope(
    tables: Mapping[str, pd.DataFrame],
    segments: pd.DataFrame,
    *,
    dataset: str,
    calibration: Mapping | None,
    sensitivity: Mapping[str, float],
    gravity_m_s2: float,
    settings: DiagnosisSettings,
) -> dict:
    """The gap diagnosis of a session scored on its rests (scope ``rests`` of
    :func:`partial_scope`).

    Its longest rest is its static recording when it lasts :data:`MIN_REST_S`
    (:func:`rest_as_static`; scope ``static``); else its rests of at least
    :data:`imucal.gap.rests.MIN_SHORT_REST_S` are pooled (:func:`imucal.gap.rests.diagnose_rests`;
    scope ``rests``); else, with a calibrated magnetometer, the residual of its field fit
    (:func:`imucal.gap.fieldfit.diagnose_field_fit`; scope ``field_fit``); else nothing is
    scored and ``reason`` says why (scope ``none``).

    Parameters
    ----------
    tables : mapping of str to DataFrame
        The session's ingested recordings by name.
    segments : DataFrame
        Its segments table.
    dataset, calibration, sensitivity, gravity_m_s2, settings
        As in :func:`diagnose_partial_session`.

    Returns
    -------
    dict
        diagnosis.json with ``static_source`` naming the rest(s) scored, or why none is.
    """
    common = dict(
        dataset=dataset, calibration=calibration, sensitivity=sensitivity,
        gravity_m_s2=gravity_m_s2, settings=settings,
    )  # fmt: skip
    static, source = rest_as_static(tables, segments)
    if static is not None:
        return diagnose_partial_session(static, static_source=source, **common)
    rests, short = session_rests(tables, segments)
    if rests:
        return diagnose_rests(rests, rests_source=f"{short}; {source}", **common)
    if short != "no rest was found":
        source = f"{source}; {short}"
    part = field_fit_part(tables, calibration, dict(sensitivity or {}))
    if not isinstance(part, str):
        return diagnose_field_fit(
            *part, source=f"{source}; the magnetometer's field fit is scored instead",
            dataset=dataset, settings=settings,
        )  # fmt: skip
    return diagnose_partial_session(None, static_source=f"{source}; field fit: {part}", **common)


def diagnose_partial_session(
    static: pd.DataFrame | None,
    *,
    motion: tuple[Mapping[str, MotionRecording], MotionTwin] | None = None,
    reference_not_scored: str | None = None,
    static_source: str | None = None,
    dataset: str,
    calibration: Mapping | None,
    sensitivity: Mapping[str, float],
    gravity_m_s2: float,
    settings: DiagnosisSettings,
    wander: bool = True,
) -> dict:
    """The gap diagnosis of a partial session from the parts it has, or why none is scored.

    Parameters
    ----------
    static : DataFrame or None
        The ingested ``static`` recording, None when the session has none.
    motion : (dict of str to MotionRecording, MotionTwin) or None
        The recordings with an orientation reference and their twin
        (:func:`imucal.gap.motion.motion_part`), None when the session has none.
    reference_not_scored : str, optional
        Why the session's recordings with a reference are not scored
        (:func:`imucal.gap.motion.reference_part`); kept in the result.
    static_source : str, optional
        Where ``static`` comes from when it is not the session's static recording (a rest,
        :func:`rest_as_static`), or why a session without one has none; kept in the result.
    dataset : str
    calibration, sensitivity, gravity_m_s2, settings, wander
        As in :func:`imucal.gap.static.diagnose_static`.

    Returns
    -------
    dict
        diagnosis.json (:func:`~imucal.gap.scoring.scored_diagnosis`) plus ``scope``
        (``static``, ``reference``, ``static+reference``), ``not_observable``, ``twin``,
        ``settings``, ``timing_s``; or :func:`~imucal.gap.static.unscored_diagnosis` with the
        reason.
    """
    streams = split_streams(static) if static is not None else {}
    if motion is None:
        extra = {"reference_not_scored": reference_not_scored} if reference_not_scored else {}
        if static_source:
            extra["static_source"] = static_source
        if static is None:
            reason = (
                "the session has neither a static recording nor a recording with an "
                "orientation reference; the twin of a partial session renders only these (its "
                "other recordings are hand-held motions nothing measures independently)"
            )
            if static_source:
                reason += f"; rests: {static_source}"
            if reference_not_scored:
                reason = (
                    "the session has no static recording, and its recordings with an "
                    f"orientation reference cannot be scored: {reference_not_scored}"
                )
            return {**unscored_diagnosis(dataset, reason), **extra}
        if not streams:
            return {
                **unscored_diagnosis(
                    dataset, "the static recording has no stream of >= 100 samples"
                ),
                **extra,
            }
        result = diagnose_static(
            static, dataset=dataset, calibration=calibration, sensitivity=sensitivity,
            gravity_m_s2=gravity_m_s2, settings=settings, wander=wander,
        )  # fmt: skip
        return {**result, **extra}
    t0 = time.perf_counter()
    recordings, motion_twin = motion
    parts, sessions, libraries = {}, {}, {}
    if streams:
        parts["static"] = build_static_twin(
            streams, calibration, dict(sensitivity or {}), gravity_m_s2, wander
        )
        sessions["static"] = streams
        libraries["static"] = scope_library("static")
    parts["motion"] = motion_twin
    sessions["motion"] = recordings
    libraries["motion"] = scope_library("motion")
    libraries = {
        part: {k: m for k, m in lib.items() if k not in settings.exclude}
        for part, lib in libraries.items()
    }
    twin = CompositeTwin(parts, {part: set(lib) for part, lib in libraries.items()})
    stats = {}
    for h in HALVES:
        stats[h] = motion_statistics(
            recordings, h, windows_s=motion_twin.windows_s, gravity_m_s2=gravity_m_s2
        )
        if streams:
            stats[h].update(static_statistics(streams, h))
    shown = set().union(*(set(lib) for lib in libraries.values()))
    # an effect neither part shows: the static recording's reason where there is one
    reasons = not_observable("motion")
    if streams:
        reasons = {**reasons, **not_observable("static")}
    return scope_diagnosis(
        twin, sessions, stats, composite_library(libraries),
        scope="static+reference" if streams else "reference",
        not_observable={k: v for k, v in reasons.items() if k not in shown},
        cannot_show="the session cannot show this effect (no such recording, stream or channel)",
        dataset=dataset, settings=settings, started=t0, beside_shortfalls=True,
    )  # fmt: skip
