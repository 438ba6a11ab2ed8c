"""The calibration of a session from its stages' artifacts: the gyroscope's (rate table or tool-free,
with the paper's Tables I and II as reference rows), the whole calibration, its application to a
recording, the validation and the figures that show what the calibration does.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from imucal import errormodel, uncertainty
from imucal.calibration import CONVENTION, FORMAT_VERSION, FRAME, ImuCalibration, SensorCalibration
from imucal.columns import ACC, GYR, MAG, PARAMETER_STD_SUFFIX, TIME, temperature_column
from imucal.fits.alignment import ALIGNMENT_RULE, phase_samples
from imucal.pipeline.outcome import not_run_reason
from imucal.pipeline.stages.gyroscope import RATE_TABLE_RULE, table_covariance
from imucal.pipeline.stages.toolfree import tool_free_gyr
from imucal.segments.table import rows_of
from imucal.validation.plausibility import bound_warnings

if TYPE_CHECKING:  # matplotlib is imported by the stages that draw, when they draw
    from matplotlib.figure import Figure

logger = logging.getLogger(__name__)

#: The paper's Tables I and II (gyroscope bias in rad/s, scale), reference rows of tables.csv.
PAPER_TABLE_I = {"paper w. tools": (0.0027, 0.1605, 0.0660), "paper LS": (-0.0022, 0.1608, 0.0679)}


PAPER_TABLE_II = {
    "paper w. tools": (1.1526, 1.1327, 1.1425),
    "paper w/o tools": (1.1526, 1.1327, 1.1411),
}


def _truth_rows(truth: Mapping | None) -> tuple[dict, dict]:
    if not truth or "gyr" not in truth:
        return {}, {}
    scale = errormodel.decompose(np.asarray(truth["gyr"]["matrix"], dtype=float)).scale
    return {"truth": tuple(truth["gyr"]["bias"])}, {"truth": tuple(scale)}


def combine_gyr(
    bias: Mapping,
    scale: Mapping | None,
    table: Mapping | None,
    table_alignment: Mapping | None,
    *,
    bias_estimator: str = "ls",
    exact: bool = True,
    truth: Mapping | None = None,
    with_covariance: bool = True,
) -> tuple[dict, pd.DataFrame]:
    """The gyroscope calibration with and without tools, and the paper's Tables I and II.

    Without tools the matrix is ``T_R,gyr diag(scale)`` with the alignment at eq. 36's scale
    (``scale['alignment']``, :func:`estimate_gyr_scale`; ``T_N,gyr`` is not observable); with a
    rate table it is ``T_R,gyr S'_gyr``. The final calibration uses the rate table when there is
    one (it observes the non-orthogonality), otherwise the tool-free result. ``scale`` is None
    when eq. 36 could not run (e.g. phases clipped at the range): then only the rate table
    calibrates, and ``tool_free`` is None. Without ``with_covariance`` (alignments from
    :func:`align_gyr` without it) the calibrations have no covariance and no std.

    Returns
    -------
    artifact : dict
        ``calibration`` (the final one), ``tool_free`` and ``ratetable`` (None without one) as
        SensorCalibration dicts, ``used``.
    tables : DataFrame
        Columns ``table, row, x, y, z``: Table I (bias, rad/s) and Table II (scale).
    """
    quality = {"alignment": {"rule": ALIGNMENT_RULE}}
    has_table = table is not None and table_alignment is not None
    if scale is None and not has_table:
        raise ValueError(
            "the gyroscope scale is known neither from a rate table nor from eq. 36 (tool-free)"
        )
    tool_free = None
    if scale is not None:
        tool_free = tool_free_gyr(
            bias,
            scale,
            bias_estimator=bias_estimator,
            exact=exact,
            with_covariance=with_covariance,
        )
    with_table = None
    table_i = {"LS (this run)": tuple(bias["bias_ls_rad_s"]), **PAPER_TABLE_I}
    table_ii = {"w/o tools (this run)": tuple(scale["scale"])} if scale is not None else {}
    table_ii.update(PAPER_TABLE_II)
    if has_table:
        rotation = np.asarray(table_alignment[table_alignment["used"]]["matrix"], dtype=float)
        upper = np.asarray(table["upper"], dtype=float)
        covariance = table_covariance(table, table_alignment, exact) if with_covariance else None
        with_table = SensorCalibration(
            "gyr",
            table["bias"],
            rotation @ upper,
            "rad/s",
            uncertainty.std_of(covariance),
            f"rate table: vector fit (eq. 33), S' = upper-triangular factor; alignment: "
            f"{table_alignment['used']} (eqs. 28-31)",
            covariance,
            {
                **quality,
                "ratetable": {
                    "dof": table["dof"],
                    "rule": RATE_TABLE_RULE,
                    **(
                        {"std_over_crlb": float(np.median(table["std_over_crlb"]))}
                        if "std_over_crlb" in table
                        else {}
                    ),
                },
            },
        )
        table_i = {"w. tools (this run)": tuple(table["bias"]), **table_i}
        table_ii = {"w. tools (this run)": tuple(np.diag(upper)), **table_ii}
    truth_i, truth_ii = _truth_rows(truth)
    rows = [
        {"table": "I", "row": name, "x": v[0], "y": v[1], "z": v[2]}
        for name, v in {**table_i, **truth_i}.items()
    ] + [
        {"table": "II", "row": name, "x": v[0], "y": v[1], "z": v[2]}
        for name, v in {**table_ii, **truth_ii}.items()
    ]
    final = with_table or tool_free
    artifact = {
        "calibration": final.to_dict(),
        "used": "ratetable" if with_table else "tool_free",
        "tool_free": tool_free.to_dict() if tool_free else None,
        "ratetable": with_table.to_dict() if with_table else None,
        "warnings": [
            *(table.get("warnings", []) if table else []),
            *bound_warnings("gyr_table" if with_table else "gyr_scale", "gyr", final.to_dict()),
        ],
    }
    return artifact, pd.DataFrame(rows, columns=["table", "row", "x", "y", "z"])


def plot_phases(
    rotation3d_lowpass: pd.DataFrame, segments: pd.DataFrame, sensor: str, calibration: Mapping
) -> Figure:
    """The filtered rotation3d phases of ``sensor`` before and after alignment.

    Paper Figs. 11-13 (accelerometer) and 18-19 (gyroscope). "Before" applies the calibration
    without its rotation ``T_R`` (the upper-triangular factor ``S'`` of ``matrix = T_R S'``, and
    the bias), "after" the whole calibration.

    Parameters
    ----------
    rotation3d_lowpass : DataFrame
        The low-pass filtered rotation3d recording, SI units.
    segments : DataFrame
    sensor : str
        'acc' or 'gyr'.
    calibration : mapping
        A SensorCalibration dict of ``sensor`` (e.g. ``acc.json['calibration']``).
    """
    from imucal.plots import inertial as inertial_plots

    if sensor not in ("acc", "gyr"):
        raise ValueError(f"phase figures are drawn for 'acc' or 'gyr', got {sensor!r}")
    cal = SensorCalibration.from_dict(sensor, dict(calibration))
    _, upper = errormodel.upper_triangular_factor(cal.matrix)
    phases = {
        label: (t, errormodel.apply(upper, cal.bias, v), errormodel.apply(cal.matrix, cal.bias, v))
        for label, (t, v) in phase_samples(rotation3d_lowpass, segments, sensor).items()
    }
    if sensor == "acc":
        return inertial_plots.plot_phases_before_after(
            phases,
            unit="m/s^2",
            quantity="specific force",
            title="Accelerometer, filtered rotation3d phases (paper Figs. 11-13)",
        )
    return inertial_plots.plot_phases_before_after(
        phases,
        unit="deg/s",
        factor=np.degrees(1.0),
        quantity="rate",
        title="Gyroscope, filtered rotation3d phases (paper Figs. 18-19)",
    )


def combine_calibration(acc: Mapping, gyr: Mapping, mag: Mapping) -> ImuCalibration:
    """The calibration of all three sensors in frame B from the stage artifacts."""
    return ImuCalibration(
        SensorCalibration.from_dict("acc", acc["calibration"]),
        SensorCalibration.from_dict("gyr", gyr["calibration"]),
        SensorCalibration.from_dict("mag", mag["calibration"]),
    )


def calibration_of_what_ran(artifacts: Mapping[str, Mapping]) -> dict:
    """calibration.json from the sensors' final artifacts, some of which may not have run.

    Parameters
    ----------
    artifacts : mapping
        ``acc``, ``gyr``, ``mag`` -> the sensor's final artifact (``acc.json``, ...) or its
        not-run record (:mod:`imucal.pipeline.outcome`).

    Returns
    -------
    dict
        :meth:`ImuCalibration.to_dict` when every sensor ran; otherwise the sensors that ran
        and ``missing`` (sensor -> the reason), the form of a partial session.
    """
    missing = {s: not_run_reason(a) for s, a in artifacts.items() if not_run_reason(a)}
    if not missing:
        return combine_calibration(artifacts["acc"], artifacts["gyr"], artifacts["mag"]).to_dict()
    ran = {
        s: SensorCalibration.from_dict(s, a["calibration"]).to_dict()
        for s, a in artifacts.items()
        if s not in missing
    }
    return {
        "format_version": FORMAT_VERSION, "frame": FRAME, "convention": CONVENTION,
        **ran, "missing": missing,
    }  # fmt: skip


def _temperature_per_sample(table: pd.DataFrame, source: str) -> np.ndarray | None:
    """The recording's temperature at every row (deg C), rows without a reading interpolated
    linearly in time from their neighbours (a channel sampled slower than acc/gyro); None
    without a temperature column."""
    col = temperature_column(table)
    if col is None:
        return None
    temp = table[col].to_numpy(dtype=float)
    ok = np.isfinite(temp)
    if not ok.any():
        raise ValueError(f"{source}: the temperature column {col!r} has no finite value")
    if ok.all():
        return temp
    t = table[TIME].to_numpy(dtype=float)
    return np.interp(t, t[ok], temp[ok])


def apply_calibration(
    table: pd.DataFrame,
    metadata: Mapping,
    calibration: ImuCalibration,
    *,
    parameter_std: bool = False,
    source: str | None = None,
) -> tuple[pd.DataFrame, dict]:
    """Calibrate the three sensors of an ingested recording to frame B.

    Every term of the calibration's model is used (:meth:`ImuCalibration.calibrate`) with what
    of the recording it needs (:attr:`imucal.modelterms.contract.ModelTerm.needs`): the temperature
    column (rows without a reading interpolated in time), the sample times. With
    ``parameter_std`` the table gains, per calibrated column, the standard deviation that the
    calibration's parameter covariance gives the sample
    (:meth:`imucal.calibration.ImuCalibration.parameter_variance`: the bias and matrix through
    their covariance and every model term through its coefficients' standard deviations;
    column name + ``_param_std``), for sensors whose calibration has a covariance or a term.

    Parameters
    ----------
    table : DataFrame
        Ingested recording (docs/architecture.md).
    metadata : dict
        Its metadata; ``units`` names the unit of each sensor and must match the calibration.
    calibration : ImuCalibration
    source : str, optional
        Name of the recording in errors (default: the metadata's ``source``).

    Returns
    -------
    table : DataFrame
        Same rows and columns, sensor values calibrated (NaN magnetometer rows stay NaN).
    metadata : dict
        With ``calibrated`` = True, ``not_calibrated`` (sensor -> reason, for a partial
        session's calibration: those readings pass through unchanged, with a warning), and
        ``model_terms`` (the terms used) and what each term reports of its flags
        (:meth:`imucal.modelterms.contract.ModelTerm.flag_report`; a temperature
        term: ``temperature_outside_span``, per sensor the fraction of samples outside the
        calibrated span, the farthest distance in K and the fraction beyond its margin,
        corrected at the margin's edge) when the model has terms.

    Raises
    ------
    ValueError
        If the recording is already calibrated, a sensor is in another unit than the
        calibration expects, the model has a temperature term and the recording has no
        temperature column, or the model has a lever arm and the recording has no gyroscope
        reading.
    """
    source = source or str(metadata.get("source", "?"))
    if metadata.get("calibrated"):
        raise ValueError(f"recording {source!r} is already calibrated")
    units = metadata.get("units", {})
    out = table.copy()
    readings, unit_of = {}, {}
    for sensor, columns in (("acc", ACC), ("gyr", GYR), ("mag", MAG)):
        found = {units.get(c) for c in columns}
        if len(found) != 1 or None in found:
            raise ValueError(
                f"recording {source!r} states the units {sorted(map(str, found))} "
                f"for {list(columns)}; expected one unit per sensor in the ingest metadata"
            )
        readings[sensor] = table[list(columns)].to_numpy(dtype=float)
        unit_of[sensor] = found.pop()
    needs = {need for term in calibration.terms.values() for need in term.needs}
    temp = _temperature_per_sample(table, source) if "temp_c" in needs else None
    t_s = table[TIME].to_numpy(dtype=float) if "t_s" in needs else None
    values, flags = calibration.calibrate(readings, unit_of, temp_c=temp, t_s=t_s, source=source)
    variance = (
        calibration.parameter_variance(readings, temp_c=temp, t_s=t_s) if parameter_std else {}
    )
    for sensor, columns in (("acc", ACC), ("gyr", GYR), ("mag", MAG)):
        out[list(columns)] = values[sensor]
        if sensor in variance:
            std = np.sqrt(variance[sensor])
            for k, column in enumerate(columns):
                out[column + PARAMETER_STD_SUFFIX] = std[:, k]
    meta = {**metadata, "calibrated": True}
    if calibration.not_calibrated:
        meta["not_calibrated"] = calibration.not_calibrated
        for sensor, reason in calibration.not_calibrated.items():
            logger.warning(
                "%s: the calibration does not calibrate %s (%s): its readings pass through",
                source, sensor, reason,
            )  # fmt: skip
    if not calibration.terms.empty:
        meta["model_terms"] = calibration.terms.names()
    for term in calibration.terms.values():
        if term.name in flags:
            entries, warnings = term.flag_report(flags[term.name], source)
            meta.update(entries)
            for warning in warnings:
                logger.warning("%s", warning)
    return out, meta


def validate_session(
    rotation3d: pd.DataFrame,
    metadata: Mapping,
    reference: pd.DataFrame | None,
    segments: pd.DataFrame,
    calibration: ImuCalibration,
    *,
    min_rate_rad_s: float = 0.2,
    n_windows: int = 6,
) -> dict:
    """Validate the calibration on the rotation3d recording (against the reference if any).

    Returns
    -------
    dict
        :func:`imucal.validation.validate` (time offset, mounting, metrics before/after, dip);
        without a reference only the reference-free checks, and it says so.
    """
    from imucal import validation

    calibrated, _ = apply_calibration(rotation3d, metadata, calibration)
    static_mask = np.zeros(len(rotation3d), dtype=bool)
    for r in rows_of(segments, "rotation3d", "static").itertuples(index=False):
        static_mask[int(r.start_index) : int(r.end_index)] = True
    result = validation.validate(
        calibrated, rotation3d, reference, static_mask, min_rate_rad_s, n_windows
    )
    return result


def plot_validation(
    rotation3d: pd.DataFrame,
    metadata: Mapping,
    reference: pd.DataFrame,
    calibration: ImuCalibration,
    validation_result: Mapping,
    *,
    n_windows: int = 6,
) -> dict[str, Figure]:
    """Figures of the validation: magnitudes (paper Fig. 20) and the cross-correlation."""
    from imucal import validation
    from imucal.plots import validation as validation_plots

    calibrated, _ = apply_calibration(rotation3d, metadata, calibration)
    # the same alignment and mounting as inside validate(), for the figures
    t_mod = validation.packet_times(rotation3d[TIME].to_numpy(), rotation3d["seq"].to_numpy())
    t_ref = validation.packet_times(reference[TIME].to_numpy(), reference["seq"].to_numpy())
    gyr_mod = calibrated[list(GYR)].to_numpy(dtype=float)
    gyr_ref = reference[list(GYR)].to_numpy(dtype=float)
    alignment = validation.estimate_time_alignment(t_mod, gyr_mod, t_ref, gyr_ref, n_windows)
    mounting = np.asarray(validation_result["mounting"]["matrix"], dtype=float)
    aligned = validation.align_reference(reference, t_mod, alignment, mounting)
    return {
        "validation_magnitudes": validation_plots.plot_magnitudes(rotation3d, calibrated, aligned),
        "validation_xcorr": validation_plots.plot_cross_correlation(
            t_mod, gyr_mod, t_ref, gyr_ref, alignment
        ),
    }
