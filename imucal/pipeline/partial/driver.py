"""The partial path's driver: its stages as nodes of the stage graph, run by the graph's runner
(:func:`imucal.pipeline.graph.run_graph`) in the registry's order with the review of each final
fit, and the choice of each sensor's final calibration among the stages that ran.
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Iterable, Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from imucal import uncertainty
from imucal.calibration import SensorCalibration
from imucal.columns import SENSORS
from imucal.fits.propagation import upper_bias_covariance
from imucal.pipeline import stages
from imucal.pipeline.graph import Node, run_graph, usable
from imucal.pipeline.options import FitMethods, PipelineOptions
from imucal.pipeline.outcome import NOT_RUN, NOT_SHIPPED, NotShipped
from imucal.pipeline.partial.accelerometer import (
    _acc_align,
    _acc_cube,
    _acc_known_orientation,
    _acc_reference,
)
from imucal.pipeline.partial.gyroscope import (
    _gyr_align,
    _gyr_bias,
    _gyr_known_rotation,
    _gyr_pose_to_pose,
    _gyr_reference,
    _gyr_scale,
    _gyr_table,
)
from imucal.pipeline.partial.magnetometer import _mag_reference, _mag_step1, _mag_step2
from imucal.pipeline.partial.session import NotApplicable, Outcome, _Session
from imucal.pipeline.registry import FINAL, STAGES

if TYPE_CHECKING:
    from imucal.io.dataset import Dataset

RUNNERS: dict[str, Callable[[_Session], dict]] = {
    "mag_step1": _mag_step1,
    "mag_step2": _mag_step2,
    "acc_known_orientation": _acc_known_orientation,
    "acc_cube": _acc_cube,
    "acc_align": _acc_align,
    "gyr_bias": _gyr_bias,
    "gyr_table": _gyr_table,
    "gyr_align": _gyr_align,
    "gyr_known_rotation": _gyr_known_rotation,
    "gyr_reference": _gyr_reference,
    "acc_reference": _acc_reference,
    "mag_reference": _mag_reference,
    "gyr_pose_to_pose": _gyr_pose_to_pose,
    "gyr_scale": _gyr_scale,
}


def _node(name: str, runner: Callable[[_Session], dict], earlier: tuple[str, ...]) -> Node:
    """A stage of the partial path as a node of the stage graph: it reads the session and the
    stages before it, and decides from them whether the session allows it (its runner raises
    :class:`NotApplicable` with the reason when it does not)."""
    sources = ("session", *earlier)

    def run(inputs: Mapping, settings: Mapping, draw: bool) -> tuple:
        session = inputs["session"]
        session.done = {k: v for k, v in inputs.items() if k != "session" and usable(v) is not None}
        return runner(session), {}

    return Node(
        name,
        f"partial/{STAGES[name].sensor}.json",
        lambda recordings: {source: source for source in sources},
        run,
        tolerates=sources,
    )


#: The partial path's stages in run order (the registry's), as nodes of the stage graph.
PARTIAL_PROTOCOL: dict[str, Node] = {
    name: _node(name, runner, tuple(RUNNERS)[:i])
    for i, (name, runner) in enumerate(RUNNERS.items())
}


def run_stages(
    tables: Mapping[str, pd.DataFrame],
    segments: pd.DataFrame,
    *,
    gravity_m_s2: float,
    field_norm: float = 1.0,
    ratetable: Mapping | None = None,
    saturation_m_s2: float | None = None,
    saturation_rad_s: float | None = None,
    notes: Mapping[str, str] | None = None,
    lowpass_order: int = 4,
    lowpass_cutoff_hz: float = 5.0,
    references: Mapping[str, tuple[pd.DataFrame, Mapping]] | None = None,
    reference_where: Mapping[str, str] | None = None,
    methods: FitMethods | None = None,
    exact_rotation: bool = True,
    stages: Collection[str] | None = None,
) -> list[Outcome]:
    """Run every stage the session allows, in :data:`STAGES` order.

    Parameters
    ----------
    tables : mapping of str to DataFrame
        Ingested recordings by name (SI units; absent sensors have no columns).
    segments : DataFrame
        Segments table of the session (automatic or from a section list).
    gravity_m_s2, field_norm : float
    ratetable : mapping, optional
        ``dataset.ratetable``.
    saturation_m_s2, saturation_rad_s : float, optional
        Sensor ranges; samples at them are left out of the fits that check it. None: the
        recordings' ranges are unknown (readers of SI data), nothing is left out.
    notes : mapping of str to str, optional
        Segmentation notes per recording (why its protocol was not found); they join the
        reasons of the stages that needed it.
    lowpass_order, lowpass_cutoff_hz : int, float
        Zero-phase Butterworth low-pass of rotation3d before the alignment stages (the
        workflow's ``lowpass`` config), cutoff in Hz.
    references : mapping, optional
        Recording -> (ingested orientation reference, its metadata) for the stage
        ``gyr_reference`` (:mod:`imucal.pipeline.reference`).
    reference_where : mapping, optional
        Recording -> key path of its reference in dataset.yaml (error messages).
    methods : FitMethods, optional
        The method of each fit (the workflow's config; defaults when None).
    exact_rotation : bool
        Exact rotation in the alignments (else the paper's small-angle form, eq. 5).
    stages : collection of str, optional
        Run only these stages (those that ran on the whole session, when the chain is run
        again on part of its data); default all.

    Returns
    -------
    list of Outcome
        One per stage of :data:`STAGES` (of ``stages`` when given).
    """
    # one options object for the stages' settings, as the in-process chain's
    ranges = {"acc": saturation_m_s2, "gyr": saturation_rad_s}
    options = PipelineOptions(
        gravity_m_s2,
        {},
        {},
        ratetable,
        field_norm,
        exact_rotation,
        lowpass_order,
        lowpass_cutoff_hz,
        methods or FitMethods(),
        ranges={sensor: value for sensor, value in ranges.items() if value is not None},
    )
    session = _Session(tables, segments, options, notes or {}, references, reference_where)
    nodes = {k: v for k, v in PARTIAL_PROTOCOL.items() if stages is None or k in stages}
    store = run_graph(
        {"session": session},
        lambda node: {},
        nodes,
        review=lambda name, artifact, store: _reviewed(name, artifact, store, session),
        reason=_reason,
    )
    outcomes = []
    for name in nodes:
        artifact = store[name]
        if NOT_RUN in artifact:
            outcomes.append(Outcome(name, "skipped", artifact[NOT_RUN]["reason"]))
            continue
        what = STAGES[name].what
        if "fallback" in artifact:  # the fit did worse than its fallback, which is shipped
            what += f"; fitted but not shipped ({artifact['fallback']['shipped']} is): "
            what += artifact["fallback"]["reason"]
        outcomes.append(Outcome(name, "run", what, artifact))
    return outcomes


def _reason(err: Exception) -> str:
    """The partial path's reason for a stage that did not run."""
    if isinstance(err, NotShipped):
        return str(err)
    if isinstance(err, NotApplicable):
        return f"not applicable: {err}"
    return f"could not be fitted: {err}"  # the fit's own message: too little or degenerate data


def _reviewed(name: str, artifact: dict, store: Mapping, session: _Session) -> dict:
    """A stage's artifact after the review of its calibration (:func:`_review`).

    A calibration that does worse than nominal on left-out data, or lies outside its sensor's
    physical bounds on weak data, is not shipped (the sensor's next, simpler stage is); one
    outside them on strong data or undetermined carries a warning.

    Raises
    ------
    NotShipped
        With the reasons of the refusal.
    """
    done = {k: v for k, v in store.items() if k in PARTIAL_PROTOCOL and usable(v) is not None}
    try:
        review = _review(name, {**done, name: artifact}, session.methods, session.exact)
    except ValueError as err:  # the review is not the data's verdict: a failure is a bug
        raise RuntimeError(f"the review of {name}'s calibration failed: {err}") from err
    if review["refuse"]:
        raise NotShipped(f"{NOT_SHIPPED}: " + "; ".join(review["refuse"]))
    # (a stage shared with the full protocol may have warned of the same value already)
    known = " ".join(artifact.get("warnings", []))
    warn = [f"{name}: {w}" for w in review["warn"]]
    warn = [w for w in warn if w.split(" against ")[0] not in known]
    if warn:
        artifact["warnings"] = [*artifact.get("warnings", []), *warn]
    return artifact


def _review(
    name: str, done: Mapping[str, dict], methods: FitMethods | None = None, exact: bool = True
) -> dict[str, list[str]]:
    """Refusals and warnings of a stage's calibration
    (:func:`imucal.validation.plausibility.review_fit`); none for stages that do not calibrate
    a sensor."""
    from imucal.validation.plausibility import review_fit

    sensor = STAGES[name].sensor
    if name not in FINAL.get(sensor, ()):
        return {"refuse": [], "warn": []}
    calibration = _calibration_of(name, done, methods or FitMethods(), exact)
    return review_fit(sensor, calibration, done[name])


def final_calibration(
    outcomes: list[Outcome], methods: FitMethods | None = None, exact_rotation: bool = True
) -> dict[str, Any]:
    """The best calibration per sensor from the stages that ran, and why a sensor has none.

    Parameters
    ----------
    outcomes : list of Outcome
        :func:`run_stages`'s.
    methods : FitMethods, optional
        The methods the stages ran with (the gyro bias estimator picks the bias).
    exact_rotation : bool
        As the stages ran (the tool-free gyroscope's combination).

    Returns
    -------
    dict
        ``sensors``: sensor -> {'stage', 'calibration' (SensorCalibration dict)};
        ``missing``: sensor -> reason.
    """
    done = {o.name: o.artifact for o in outcomes if o.status == "run"}
    sensors, missing = {}, {}
    for sensor in SENSORS:
        stage = next((s for s in FINAL[sensor] if s in done), None)
        if stage is None:
            missing[sensor] = "no stage of this sensor could run: " + "; ".join(
                f"{o.name}: {o.reason}" for o in outcomes if o.name in FINAL[sensor]
            )
            continue
        calibration = _calibration_of(stage, done, methods or FitMethods(), exact_rotation)
        sensors[sensor] = {"stage": stage, "calibration": calibration}
    return {"sensors": sensors, "missing": missing}


def _calibration_of(
    stage: str,
    done: Mapping[str, dict],
    methods: FitMethods | None = None,
    exact: bool = True,
) -> dict:
    """The calibration (dict form) a stage's artifact gives its sensor, with the session's fit
    methods (the defaults when None) and rotation form."""
    methods = methods or FitMethods()
    artifact = done[stage]
    if stage == "mag_step1":
        from imucal.fits import magnetometer

        fit = magnetometer.EllipsoidFit.from_dict(dict(artifact))
        cov = uncertainty.step1_only_covariance(fit.upper, fit.bias, fit.selected.covariance)
        return SensorCalibration(
            "mag",
            fit.bias,
            fit.upper,
            "normalised",
            uncertainty.std_of(cov),
            "ellipsoid fit only (step 1, no T_R)",
            cov,
        ).to_dict()
    if stage == "gyr_table":
        shift = np.asarray(artifact.get("cut_shift", np.zeros(12)), dtype=float)
        cov9 = upper_bias_covariance(
            artifact["matrix"], np.asarray(artifact["covariance"]) + np.outer(shift, shift)
        )
        cov = uncertainty.step1_only_covariance(artifact["upper"], artifact["bias"], cov9)
        return SensorCalibration(
            "gyr",
            artifact["bias"],
            artifact["upper"],
            "rad/s",
            uncertainty.std_of(cov),
            "rate table (eq. 33), no T_R",
            cov,
        ).to_dict()
    if stage == "gyr_scale":
        return stages.tool_free_gyr(
            done["gyr_bias"], artifact, bias_estimator=methods.gyr_bias_estimator, exact=exact
        ).to_dict()
    if stage == "gyr_bias":
        # the wander's variance where it shows
        bias, std = stages.gyr_bias_value(artifact, methods.gyr_bias_estimator)
        return SensorCalibration(
            "gyr",
            bias,
            np.eye(3),
            "rad/s",
            {"bias": std},
            "bias only (nominal scale, sensor frame)",
            quality=stages.gyr_bias_quality(artifact),
        ).to_dict()
    return dict(artifact["calibration"])


def session_keywords(
    dataset: Dataset,
    metadata: Iterable[Mapping],
    notes: Mapping[str, str],
    references: Mapping[str, tuple[pd.DataFrame, Mapping]],
    settings: Mapping,
) -> dict[str, Any]:
    """The keywords of :func:`run_stages` for a session as the workflow reads it.

    Parameters
    ----------
    dataset : Dataset
        The session's ``dataset.yaml``.
    metadata : iterable of mapping
        The ingested recordings' metadata (their sensors' ranges, :func:`imucal.ingest.sensor_limits`).
    notes : mapping of str to str
        The segmentation's notes (the segments' metadata ``notes``).
    references : mapping
        Recording -> (ingested orientation reference, its metadata).
    settings : mapping
        The pipeline's settings (:func:`imucal.pipeline.options.pipeline_settings`).

    Returns
    -------
    dict
        Every keyword of :func:`run_stages` but the tables, the segments and ``stages``.
    """
    from imucal.ingest import sensor_limits

    # readings at a sensor's range are clipped: the fits leave them out where the range is known
    limits = sensor_limits(metadata, dataset.range_counts)
    return {
        "gravity_m_s2": dataset.gravity_m_s2,
        "field_norm": dataset.field_norm,
        "ratetable": dataset.ratetable,
        "saturation_m_s2": limits.get("acc"),
        "saturation_rad_s": limits.get("gyr"),
        "notes": dict(notes),
        "lowpass_order": settings["lowpass_order"],
        "lowpass_cutoff_hz": settings["lowpass_cutoff_hz"],
        "references": dict(references),
        "reference_where": {name: dataset.reference_where(name) for name in references},
        "methods": FitMethods.of(settings["methods"]),
        "exact_rotation": settings["exact_rotation"],
    }
