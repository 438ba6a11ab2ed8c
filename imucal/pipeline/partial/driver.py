"""The partial path's driver: its stages as nodes of the stage graph, run by the graph's runner
(:func:`imucal.pipeline.graph.run_graph`) in the registry's order with the review of each final
fit, and the choice of each sensor's final calibration among the stages that ran.
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Mapping
from typing import Any

import numpy as np

from imucal import uncertainty
from imucal.calibration import SensorCalibration
from imucal.columns import SENSORS
from imucal.fits.propagation import upper_bias_covariance
from imucal.pipeline import stages
from imucal.pipeline.graph import Node, run_graph, usable
from imucal.pipeline.options import FitMethods, PipelineOptions
from imucal.pipeline.outcome import NOT_RUN, NOT_SHIPPED, NotShipped
from imucal.pipeline.partial import accelerometer as acc
from imucal.pipeline.partial import gyroscope as gyr
from imucal.pipeline.partial import magnetometer as mag
from imucal.pipeline.partial.listing import PartialFiles, calibration_file, stage_results
from imucal.pipeline.partial.session import NotApplicable, Outcome, Session
from imucal.pipeline.registry import FINAL, STAGES

#: A runner: ``runner(session, done) -> artifact``, ``done`` holding the artifacts of the stages
#: it reads that ran (:data:`READS`); it raises :class:`NotApplicable` with the reason when the
#: session does not allow the stage.
Runner = Callable[[Session, Mapping[str, dict]], dict]

#: The partial path's stages in run order (the registry's), each with its runner.
RUNNERS: dict[str, Runner] = {
    "mag_step1": mag.mag_step1,
    "mag_step2": mag.mag_step2,
    "acc_known_orientation": acc.acc_known_orientation,
    "acc_cube": acc.acc_cube,
    "acc_align": acc.acc_align,
    "gyr_bias": gyr.gyr_bias,
    "gyr_table": gyr.gyr_table,
    "gyr_align": gyr.gyr_align,
    "gyr_known_rotation": gyr.gyr_known_rotation,
    "gyr_reference": gyr.gyr_reference,
    "acc_reference": acc.acc_reference,
    "mag_reference": mag.mag_reference,
    "gyr_pose_to_pose": gyr.gyr_pose_to_pose,
    "gyr_scale": gyr.gyr_scale,
}

#: The earlier stages whose artifacts each stage reads (its node's inputs besides the session);
#: one that did not run is left out of ``done`` and the runner decides without it.
READS: dict[str, tuple[str, ...]] = {
    "mag_step1": (),
    "mag_step2": ("mag_step1",),
    "acc_known_orientation": (),
    "acc_cube": (),
    "acc_align": ("acc_cube",),
    "gyr_bias": (),
    "gyr_table": (),
    "gyr_align": ("gyr_bias",),
    "gyr_known_rotation": ("gyr_bias",),
    "gyr_reference": ("gyr_bias",),
    "acc_reference": ("gyr_reference",),
    "mag_reference": ("mag_step1", "gyr_reference"),
    "gyr_pose_to_pose": ("gyr_bias", *FINAL["acc"]),
    "gyr_scale": ("gyr_bias", "gyr_align", "acc_align", "mag_step2"),
}


def _node(name: str, runner: Runner, reads: tuple[str, ...]) -> Node:
    """A stage of the partial path as a node of the stage graph: it reads the session and the
    artifacts of the stages ``reads``, and decides from them whether the session allows it (its
    runner raises :class:`NotApplicable` with the reason when it does not)."""
    sources = ("session", *reads)

    def run(inputs: Mapping, settings: Mapping, draw: bool) -> tuple:
        done = {k: v for k, v in inputs.items() if k != "session" and usable(v) is not None}
        return runner(inputs["session"], done), {}

    return Node(
        name,
        f"partial/{STAGES[name].sensor}.json",
        lambda recordings: {source: source for source in sources},
        run,
        tolerates=sources,
    )


#: The partial path's stages in run order (the registry's), as nodes of the stage graph.
PARTIAL_PROTOCOL: dict[str, Node] = {
    name: _node(name, runner, READS[name]) for name, runner in RUNNERS.items()
}


def run_stages(session: Session, stages: Collection[str] | None = None) -> list[Outcome]:
    """Run every stage the session allows, in :data:`STAGES` order.

    Parameters
    ----------
    session : Session
        The session's recordings, segments, options and references.
    stages : collection of str, optional
        Run only these stages (those that ran on the whole session, when the chain is run
        again on part of its data); default all.

    Returns
    -------
    list of Outcome
        One per stage of :data:`STAGES` (of ``stages`` when given).
    """
    nodes = {k: v for k, v in PARTIAL_PROTOCOL.items() if stages is None or k in stages}
    store = run_graph(
        {"session": session},
        lambda node: {},
        nodes,
        review=lambda name, artifact, store: _reviewed(name, artifact, store, session.options),
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


def _reviewed(name: str, artifact: dict, store: Mapping, options: PipelineOptions) -> dict:
    """A stage's artifact after the review of its calibration (:func:`review`).

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
        found = review(name, {**done, name: artifact}, options.methods, options.exact_rotation)
    except ValueError as err:  # the review is not the data's verdict: a failure is a bug
        raise RuntimeError(f"the review of {name}'s calibration failed: {err}") from err
    if found["refuse"]:
        raise NotShipped(f"{NOT_SHIPPED}: " + "; ".join(found["refuse"]))
    # (a stage shared with the full protocol may have warned of the same value already)
    known = " ".join(artifact.get("warnings", []))
    warn = [f"{name}: {w}" for w in found["warn"]]
    warn = [w for w in warn if w.split(" against ")[0] not in known]
    if warn:
        artifact["warnings"] = [*artifact.get("warnings", []), *warn]
    return artifact


def review(
    name: str, done: Mapping[str, dict], methods: FitMethods | None = None, exact: bool = True
) -> dict[str, list[str]]:
    """Refusals and warnings of a stage's calibration with the session's fit methods (the
    defaults when None) and rotation form
    (:func:`imucal.validation.plausibility.review_fit`); none for stages that do not calibrate
    a sensor."""
    from imucal.validation.plausibility import review_fit

    sensor = STAGES[name].sensor
    if name not in FINAL.get(sensor, ()):
        return {"refuse": [], "warn": []}
    calibration = calibration_of(name, done, methods or FitMethods(), exact)
    return review_fit(sensor, calibration, done[name])


def final_calibration(outcomes: list[Outcome], options: PipelineOptions) -> dict[str, Any]:
    """The best calibration per sensor from the stages that ran, and why a sensor has none.

    Parameters
    ----------
    outcomes : list of Outcome
        :func:`run_stages`'s.
    options : PipelineOptions
        The options the stages ran with (the gyro bias estimator picks the bias; the rotation
        form gives the tool-free gyroscope's combination).

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
        calibration = calibration_of(stage, done, options.methods, options.exact_rotation)
        sensors[sensor] = {"stage": stage, "calibration": calibration}
    return {"sensors": sensors, "missing": missing}


def calibration_of(
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


def calibrate_partial(session: Session, dataset: str) -> PartialFiles:
    """Run the stages a partial session allows and gather what its files hold.

    Parameters
    ----------
    session : Session
    dataset : str
        The dataset's name (``stages.json``).

    Returns
    -------
    PartialFiles
        The outcomes, ``calibration.json`` (before any temperature terms), ``stages.json`` and
        the artifacts per sensor.
    """
    outcomes = run_stages(session)
    final = final_calibration(outcomes, session.options)
    return PartialFiles(
        outcomes,
        calibration_file(final),
        {"dataset": dataset, "stages": [o.summary() for o in outcomes]},
        stage_results(outcomes),
    )
