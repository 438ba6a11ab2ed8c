"""The paper's whole chain run in process on in-memory tables: segment, filter, fit, combine.

:func:`calibrate_session` calls the stage functions of :mod:`imucal.pipeline.stages` in the
workflow's order, with the workflow's fallbacks, without Snakemake and without files. The gap
diagnosis calibrates a recorded session and its twin replicas with it (their statistics must
come from one code path), and the tests check the chain against known truth with it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd

from imucal import validation
from imucal.calibration import ImuCalibration
from imucal.columns import GYR, SEQ, TIME, column_values, sensor_columns
from imucal.pipeline import stages
from imucal.pipeline.graph import FULL_PROTOCOL, run_nodes, usable
from imucal.pipeline.options import PipelineOptions
from imucal.pipeline.outcome import not_run_reason
from imucal.segments.filtering import lowpass_recording
from imucal.segments.segmentation import segment_dataset


@dataclass(frozen=True)
class SessionFit:
    """Everything the pipeline produced for one session (real or replica).

    Attributes
    ----------
    imu : dict of str to DataFrame
        Ingested IMU recordings.
    reference : DataFrame or None
    segments : DataFrame
    lowpass : DataFrame
        Low-pass filtered rotation3d.
    calibration : ImuCalibration
    artifacts : dict
        Each stage's artifact by its name (:data:`~imucal.pipeline.graph.FULL_PROTOCOL`); None
        for a stage that did not run or does not apply (the rate table's without one).
    time_alignment : TimeAlignment or None
        Reference clock against rotation3d (None without a reference).
    reference_start_s : float or None
        ``t_s`` of the reference's first sample (its own clock).
    extra : dict
        ``options`` (as run, with ``held_by_hand`` from the segments), ``notes`` (the stages
        that did not run although the calibration did, with their reasons), ``records`` (each
        stage's artifact or not-run record, as the workflow writes them).
    """

    imu: dict
    reference: pd.DataFrame | None
    segments: pd.DataFrame
    lowpass: pd.DataFrame
    calibration: ImuCalibration
    artifacts: dict
    time_alignment: object | None
    reference_start_s: float | None
    extra: dict = field(default_factory=dict)


def calibrate_session(
    imu: Mapping[str, pd.DataFrame],
    reference: pd.DataFrame | None,
    options: PipelineOptions,
    segments: pd.DataFrame | None = None,
    *,
    done: Mapping[str, Mapping] | None = None,
) -> SessionFit:
    """Segment (unless ``segments`` is given) and calibrate a session, stage by stage.

    Parameters
    ----------
    imu : dict of str to DataFrame
        Ingested IMU recordings ('rotation3d' and 'cube' required; 'ratetable', 'static'
        optional), SI units.
    reference : DataFrame or None
        Ingested reference (its own axes and clock).
    options : PipelineOptions
    segments : DataFrame, optional
        The segments table; automatic segmentation when None.
    done : dict of str to dict, optional
        Stage name -> artifact (or not-run record) of stages already run on this session with
        these options and ``segments``: the workflow's own rules' (their JSON files). Those
        stages are taken as they are and not run again.

    Returns
    -------
    SessionFit
    """
    missing = [r for r in ("rotation3d", "cube") if r not in imu]
    if missing:
        raise ValueError(f"the gap diagnosis needs the recordings {missing}; got {sorted(imu)}")
    imu = dict(imu)
    if segments is None:  # as the workflow: a recording whose protocol is not found keeps poses
        segments = segment_dataset(
            imu, ratetable=dict(options.ratetable or {}) or None, fallback=True
        )
    held = sorted(set(options.held_by_hand) | set(segments.attrs.get("held_by_hand", [])))
    options = replace(options, held_by_hand=tuple(held))
    low = lowpass_recording(
        imu["rotation3d"], order=options.lowpass_order, cutoff_hz=options.lowpass_cutoff_hz
    )
    done = dict(done or {})
    store = run_nodes(
        {**imu, "lowpass": low, "segments": segments, **done},
        options,
        nodes={name: node for name, node in FULL_PROTOCOL.items() if name not in done},
    )
    records = {name: store[name] for name in FULL_PROTOCOL if name in store}
    artifacts = {name: usable(records.get(name)) for name in FULL_PROTOCOL}
    reasons = {name: not_run_reason(record) for name, record in records.items()}
    for final in ("mag_step2", "acc_align", "gyr"):  # each sensor's calibration
        if reasons[final]:
            raise ValueError(reasons[final])
    # a stage that did not run although the calibration did (eq. 36 beside a rate table, the
    # rate table's fit beside eq. 36): the diagnosis goes on and says so
    notes = [reason for reason in reasons.values() if reason]
    calibration = stages.combine_calibration(
        artifacts["acc_align"], artifacts["gyr"], artifacts["mag_step2"]
    )
    alignment = start = None
    if reference is not None:
        alignment = reference_alignment(imu["rotation3d"], reference, calibration)
        start = float(reference[TIME].iloc[0])
    return SessionFit(
        imu,
        reference,
        segments,
        low,
        calibration,
        artifacts,
        alignment,
        start,
        {"options": options, "notes": notes, "records": records},
    )


def refit_alignment(fit: SessionFit, *, exact: bool) -> ImuCalibration:
    """The session's calibration with the alignment stages refitted in the given form.

    Repeats step 2 of each sensor (``align_mag``, ``align_acc``, ``align_gyr`` and the rate
    table's alignment) and ``combine_gyr`` on the session's stage-1 artifacts, with the exact
    rotation or the paper's small-angle form (eq. 5). The tool-free gyro scale (eq. 36) is
    kept from the session's fit and its alignment refitted as the fit did it (at the first
    pass's scale, :func:`~imucal.pipeline.stages.estimate_gyr_scale`): the scale enters
    only without a rate table, and its dependence on the alignment form is of higher order
    than the alignment's own. The covariance is carried as in the fit (``with_covariance`` of
    its options).

    Parameters
    ----------
    fit : SessionFit
    exact : bool
        Exact rotation (True) or the small-angle form (False).

    Returns
    -------
    ImuCalibration
    """
    options = replace(fit.extra["options"], exact_rotation=exact)
    store = {**fit.imu, "lowpass": fit.lowpass, "segments": fit.segments, **fit.extra["records"]}
    scale = fit.artifacts["gyr_scale"]
    if scale is not None:
        refit = stages.align_gyr(
            fit.lowpass,
            fit.segments,
            stages.gyr_bias_value(fit.artifacts["gyr_bias"], options.methods.gyr_bias_estimator)[0],
            np.diag(scale["first_pass_scale"]),  # as the fit refitted it
            method=scale["alignment"]["used"],
            exact=exact,
            with_covariance=options.with_covariance,
        )
        store["gyr_scale"] = {**scale, "alignment": refit}
    steps = ("mag_step2", "acc_align", "gyr_table_align", "gyr")
    store = run_nodes(store, options, nodes={name: FULL_PROTOCOL[name] for name in steps})
    return stages.combine_calibration(store["acc_align"], store["gyr"], store["mag_step2"])


def reference_alignment(
    rotation3d: pd.DataFrame, reference: pd.DataFrame, calibration: ImuCalibration
):
    """Clock offset and drift of the reference against rotation3d (validation's estimator).

    Returns
    -------
    imucal.validation.TimeAlignment
    """
    t_mod = validation.packet_times(rotation3d[TIME].to_numpy(), rotation3d[SEQ].to_numpy())
    t_ref = validation.packet_times(reference[TIME].to_numpy(), reference[SEQ].to_numpy())
    gyr_mod = calibration.sensor("gyr").apply(column_values(rotation3d, GYR), unit="rad/s")
    gyr_ref = column_values(reference, GYR)
    return validation.estimate_time_alignment(t_mod, gyr_mod, t_ref, gyr_ref, 6)


def calibrated(fit: SessionFit, recording: str, sensor: str) -> np.ndarray:
    """Calibrated values (frame B, SI) of one sensor of one recording, shape (n, 3).

    Computed once per fit (the diagnosis's statistics ask for the same recording many times)
    and returned read-only, so that no caller can change what the next one gets.
    """
    cache = fit.extra.setdefault("calibrated", {})
    if (recording, sensor) not in cache:
        values = column_values(fit.imu[recording], sensor_columns(sensor))
        cal = fit.calibration.sensor(sensor)
        out = cal.apply(values, unit=cal.unit)
        out.flags.writeable = False
        cache[(recording, sensor)] = out
    return cache[(recording, sensor)]
