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
from imucal.pipeline.options import PipelineOptions
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
        Stage artifacts: 'mag', 'cube', 'acc', 'bias', 'align', 'scale', 'table' (None without a
        rate table), 'gyr'.
    time_alignment : TimeAlignment or None
        Reference clock against rotation3d (None without a reference).
    reference_start_s : float or None
        ``t_s`` of the reference's first sample (its own clock).
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
    exact, cov, methods = options.exact_rotation, options.with_covariance, options.methods
    step1 = stages.fit_mag_step1(
        imu["rotation3d"],
        imu["cube"],
        field_norm=options.field_norm,
        refine_lm=methods.mag_refine_lm,
    )
    mag = stages.align_mag(
        imu["rotation3d"],
        segments,
        step1,
        method=methods.mag_alignment,
        exact=exact,
        with_covariance=cov,
    )
    cube, _ = stages.fit_acc_cube(
        imu["cube"],
        segments,
        gravity_m_s2=options.gravity_m_s2,
        saturation_limit_m_s2=options.limit("acc"),
        method=methods.acc_cube,
        figures=False,
    )
    acc = stages.align_acc(
        low, segments, cube, method=methods.acc_alignment, exact=exact, with_covariance=cov
    )
    bias, _ = stages.estimate_gyr_bias(imu, segments, figures=False)
    o, _ = stages.gyr_bias_value(bias, methods.gyr_bias_estimator)
    align = stages.align_gyr(
        low, segments, o, method=methods.gyr_alignment, exact=exact, with_covariance=cov
    )
    notes = []
    try:
        scale = stages.estimate_gyr_scale(
            imu["rotation3d"],
            low,
            segments,
            bias,
            align,
            acc,
            mag,
            bias_estimator=methods.gyr_bias_estimator,
            with_covariance=cov,
        )
    except ValueError as err:
        # eq. 36 integrates on the receive timestamps and refuses repeated ones, or phases
        # clipped at the range; with a rate table the final calibration does not need it, so
        # the diagnosis goes on and says so
        if "ratetable" not in imu:
            raise
        notes.append(f"eq. 36 (gyro scale without tools) failed: {err}")
        scale = None
    table = table_align = None
    if "ratetable" in imu:
        try:
            table, _ = stages.fit_gyr_table(
                imu["ratetable"],
                segments,
                saturation_limit_rad_s=options.limit("gyr"),
                figures=False,
            )
            table_align = _align_table(low, segments, table, options, exact)
        except ValueError as err:
            # as the workflow: the tool-free result calibrates when eq. 36 ran
            if scale is None:
                raise
            notes.append(f"rate-table fit (eq. 33) failed: {err}; the tool-free result is used")
            table = table_align = None
    gyr = _combine_gyr(bias, scale, table, table_align, options, exact)
    calibration = stages.combine_calibration(acc, gyr, mag)
    alignment = start = None
    if reference is not None:
        alignment = reference_alignment(imu["rotation3d"], reference, calibration)
        start = float(reference[TIME].iloc[0])
    artifacts = {
        "mag": mag, "cube": cube, "acc": acc, "bias": bias, "align": align, "scale": scale,
        "table": table, "gyr": gyr,
    }  # fmt: skip
    return SessionFit(
        imu,
        reference,
        segments,
        low,
        calibration,
        artifacts,
        alignment,
        start,
        {"options": options, "notes": notes},
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
    a, low, seg = fit.artifacts, fit.lowpass, fit.segments
    options = fit.extra["options"]
    cov, methods = options.with_covariance, options.methods
    mag = stages.align_mag(
        fit.imu["rotation3d"],
        seg,
        a["mag"]["step1"],
        method=methods.mag_alignment,
        exact=exact,
        with_covariance=cov,
    )
    acc = stages.align_acc(
        low, seg, a["cube"], method=methods.acc_alignment, exact=exact, with_covariance=cov
    )
    o, _ = stages.gyr_bias_value(a["bias"], methods.gyr_bias_estimator)
    scale = a["scale"]
    if scale is not None:
        refit = stages.align_gyr(
            low,
            seg,
            o,
            np.diag(scale["first_pass_scale"]),  # as the fit refitted it
            method=scale["alignment"]["used"],
            exact=exact,
            with_covariance=cov,
        )
        scale = {**scale, "alignment": refit}
    table_align = None
    if a["table"] is not None:
        table_align = _align_table(low, seg, a["table"], options, exact)
    gyr = _combine_gyr(a["bias"], scale, a["table"], table_align, options, exact)
    return stages.combine_calibration(acc, gyr, mag)


def _align_table(
    low: pd.DataFrame, segments: pd.DataFrame, table: Mapping, options: PipelineOptions, exact: bool
) -> dict:
    """``T_R,gyr`` at the rate table's bias and ``S'_gyr`` (its alignment stage)."""
    return stages.align_gyr(
        low,
        segments,
        table["bias"],
        table["upper"],
        method=options.methods.gyr_alignment,
        exact=exact,
        with_covariance=options.with_covariance,
    )


def _combine_gyr(bias, scale, table, table_align, options: PipelineOptions, exact: bool) -> dict:
    """The gyroscope's calibration from its stages (rate table, else eq. 36), as rule gyr."""
    gyr, _ = stages.combine_gyr(
        bias,
        scale,
        table,
        table_align,
        bias_estimator=options.methods.gyr_bias_estimator,
        exact=exact,
        with_covariance=options.with_covariance,
    )
    return gyr


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
