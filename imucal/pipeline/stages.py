"""The accelerometer and gyroscope stages of the workflow, as functions of their input tables.

Each function is what one rule runs: it cuts the segments it needs out of the ingested (or
low-pass filtered) tables, calls the fits of :mod:`imucal.fits.accelerometer`,
:mod:`imucal.fits.gyroscope` and :mod:`imucal.fits.alignment`, and returns a JSON-ready artifact (and
figures, never saved here). Stages exchange their results through these artifacts, so one stage
can be rerun on new data.

The module is long (about 1150 lines) because it has one function per rule of the paper's
stage-per-rule path; the in-process chain (:mod:`imucal.pipeline.full`) and the partial path
(:mod:`imucal.pipeline.partial`) call the same functions, so a stage is written once.
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from imucal import errormodel, uncertainty
from imucal.calibration import CONVENTION, FORMAT_VERSION, FRAME, ImuCalibration, SensorCalibration
from imucal.columns import (
    ACC,
    AXES,
    GYR,
    MAG,
    PARAMETER_STD_SUFFIX,
    TIME,
    column_values,
    temperature_column,
)
from imucal.fits import accelerometer, gyroscope
from imucal.fits.alignment import (
    ALIGNMENT_RULE,
    align_constant_component,
    align_rotation_axis,
    phase_samples,
)
from imucal.fits.propagation import alignment_sensitivity, upper_bias_covariance
from imucal.fits.ratetable import fit_rate_table, rate_table_crlb
from imucal.pipeline.outcome import not_run_reason
from imucal.segments.detector import is_clipped
from imucal.segments.table import cut, rows_of
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
ALIGNMENT_METHODS = ("full", "paper")
#: How the rate table's covariance is scaled (for the calibration's ``quality``).
RATE_TABLE_RULE = (
    "noise per axis from the runs' residuals about the fit (dof = n_runs - 4), plus the outer "
    "product of the shift of (K, b) when every run loses its outer tenths (cut_shift)"
)
#: What the tool-free gyroscope's covariance leaves out.
TOOL_FREE_RULE = (
    "T_N is not observable without a rate table and is taken as exact (xi = 0, std 0); eq. 36's "
    "scale std from the integrated noise and the spread of the acc/mag angles"
)


def plain(obj):
    """JSON-ready copy of a dataclass / dict / array tree."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: plain(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, Mapping):
        return {str(k): plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [plain(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    return obj


def _saturated(values: np.ndarray, limit: float) -> np.ndarray:
    """Rows of ``values`` (n, 3) with any axis at or beyond the sensor range ``limit``."""
    return np.any(np.abs(values) >= limit, axis=1)


def _phases(table: pd.DataFrame, segments: pd.DataFrame, sensor: str) -> dict[str, np.ndarray]:
    """Phase label -> the sensor's samples (n, 3) in that rotation3d phase."""
    return {label: values for label, (_, values) in phase_samples(table, segments, sensor).items()}


def fit_acc_cube(
    cube: pd.DataFrame,
    segments: pd.DataFrame,
    *,
    gravity_m_s2: float,
    saturation_limit_m_s2: float,
    method: str = "means",
    figures: bool = True,
) -> tuple[dict, dict[str, Figure]]:
    """Accelerometer step 1 (eq. 32) on the static cube positions.

    Parameters
    ----------
    cube : DataFrame
        Ingested cube recording (m/s^2).
    segments : DataFrame
        Segments table; rows of kind 'position' of 'cube'.
    gravity_m_s2 : float
    saturation_limit_m_s2 : float
        ``range_counts * sensitivity`` of the accelerometer; samples at it are excluded.
    method : {'means', 'samples'}
        See :func:`imucal.fits.accelerometer.fit_cube`.
    figures : bool
        Draw the figure (the in-process chain does not need it).

    Returns
    -------
    artifact : dict
        The fit (``upper`` = S'_acc, ``bias``, std, per-position residuals before/after, warnings).
    figures : dict of str to Figure
        'acc_cube': |a| - g per position before/after (paper Fig. 10).
    """
    from imucal.plots import inertial as inertial_plots

    rows = rows_of(segments, "cube", "position")
    positions = cut(cube, rows, ACC)
    fit = accelerometer.fit_cube(
        positions,
        gravity_m_s2,
        labels=[str(label) for label in rows["label"]],
        saturation_limit_m_s2=saturation_limit_m_s2,
        method=method,
    )
    artifact = plain(fit)
    artifact["gravity_m_s2"] = gravity_m_s2
    if not figures:
        return artifact, {}
    return artifact, {"acc_cube": inertial_plots.plot_cube_magnitude_errors(fit)}


def align_acc(
    rotation3d_lowpass: pd.DataFrame,
    segments: pd.DataFrame,
    cube_fit: Mapping,
    *,
    method: str = "full",
    exact: bool = True,
    with_covariance: bool = True,
) -> dict:
    """Accelerometer step 2: ``T_R,acc`` from the low-pass filtered rotation3d phases.

    Only phases whose axis is horizontal sweep gravity; :func:`align_constant_component` skips
    the others (the z phase) and says why. Both methods are computed; ``method`` is used.
    Without ``with_covariance`` the calibration has no covariance and no std (step 1's
    uncertainty is not carried through the alignment) and the alignments' own covariance is
    the plain one (``correlated=False``), for callers that read fitted values only.

    Returns
    -------
    dict
        ``calibration`` (SensorCalibration dict, ``matrix = T_R S'``), ``step2`` (both methods and
        which was used), ``step1`` (the cube fit it builds on).
    """
    upper = np.asarray(cube_fit["upper"], dtype=float)
    bias = np.asarray(cube_fit["bias"], dtype=float)
    raw = _phases(rotation3d_lowpass, segments, "acc")
    phases = {label: errormodel.apply(upper, bias, values) for label, values in raw.items()}
    alignments = {
        name: align_constant_component(phases, method=name, exact=exact, correlated=with_covariance)
        for name in ALIGNMENT_METHODS
    }
    fit, step1 = cube_quality(cube_fit)
    covariance = None
    if with_covariance:
        covariance = uncertainty.two_step_covariance(
            upper,
            bias,
            step1,
            alignments[method].alpha_rad,
            alignments[method].covariance,
            alignment_sensitivity(
                lambda ph: align_constant_component(
                    ph, method=method, exact=exact, correlated=False
                ),
                raw,
                upper,
                bias,
            ),
            exact,
        )
    calibration = SensorCalibration(
        "acc",
        bias,
        alignments[method].matrix @ upper,
        "m/s^2",
        uncertainty.std_of(covariance),
        f"step 1: cube fit ({cube_fit['method']}); step 2: {method} "
        f"({'exact rotation' if exact else 'small-angle eq. 5'})",
        covariance,
        {
            # the cube fit's covariance is its Cramer-Rao bound to first order (noise-weighted
            # Jacobian at the solution): only the inflation sets it apart
            "cube": fit,
            "alignment": {"rule": ALIGNMENT_RULE},
        },
    )
    return {
        "calibration": calibration.to_dict(),
        "step1": dict(cube_fit),
        "step2": {"used": method, **{k: a.to_dict() for k, a in alignments.items()}},
        "warnings": [
            *cube_fit.get("warnings", []),
            *bound_warnings("acc_align", "acc", calibration.to_dict()),
        ],
    }


def cube_quality(cube_fit: Mapping) -> tuple[dict, np.ndarray]:
    """The cube fit's goodness of fit and its covariance of (S' entries, o), inflated by its rule.

    Returns
    -------
    quality : dict
        :meth:`imucal.uncertainty.GoodnessOfFit.to_dict` with ``std_over_crlb`` (the cube fit's
        covariance is its Cramer-Rao bound to first order, the noise-weighted Jacobian at the
        solution: only the inflation sets it apart); without degrees of freedom (as many
        positions as parameters) the rule says so and nothing is inflated.
    covariance : ndarray, shape (9, 9)
    """
    covariance = np.asarray(cube_fit["covariance"], dtype=float)
    if cube_fit["dof"] < 1:
        rule = "no goodness of fit: as many position means as parameters, nothing inflated"
        return {"dof": int(cube_fit["dof"]), "inflation": 1.0, "rule": rule}, covariance
    fit = uncertainty.goodness_of_fit(cube_fit["chi2"], cube_fit["dof"])
    quality = {**fit.to_dict(), "std_over_crlb": float(np.sqrt(fit.inflation))}
    return quality, fit.inflation * covariance


def cube_calibration(cube_fit: Mapping) -> SensorCalibration:
    """The accelerometer from the cube fit alone (eq. 32; sensor frame, no ``T_R``) with the
    covariance of every parameter, inflated by the fit's goodness of fit."""
    upper = np.asarray(cube_fit["upper"], dtype=float)
    bias = np.asarray(cube_fit["bias"], dtype=float)
    quality, step1 = cube_quality(cube_fit)
    covariance = uncertainty.step1_only_covariance(upper, bias, step1)
    return SensorCalibration(
        "acc",
        bias,
        upper,
        "m/s^2",
        uncertainty.std_of(covariance),
        "cube fit (eq. 32), sensor frame (no T_R)",
        covariance,
        {"cube": quality},
    )


def estimate_gyr_bias(
    static_tables: Mapping[str, pd.DataFrame], segments: pd.DataFrame, *, figures: bool = True
) -> tuple[dict, dict[str, Figure]]:
    """Gyroscope bias (eqs. 34-35 and the plain mean) from the static recording.

    Without a static recording, the static pauses of the other recordings are used.

    Parameters
    ----------
    static_tables : dict of str to DataFrame
        Ingested recordings by name; 'static' is used when present, else 'rotation3d' and 'cube'.
    segments : DataFrame
    figures : bool
        Draw the figure (the in-process chain does not need it).

    Returns
    -------
    artifact : dict
    figures : dict of str to Figure
        'gyr_bias': the static rates before and after bias removal (Figs. 16-17).
    """
    from imucal.plots import inertial as inertial_plots

    names = (
        ["static"]
        if "static" in static_tables
        else [n for n in ("rotation3d", "cube") if n in static_tables]
    )
    pieces, times = [], []
    for name in names:
        rows = rows_of(segments, name, "static")
        if name == "cube":
            rows = pd.concat([rows, rows_of(segments, name, "position")])
        pieces += cut(static_tables[name], rows, GYR)
        times += cut(static_tables[name], rows, (TIME,))
    if not pieces:
        raise ValueError(
            f"no static segment found in the recordings {names}; the gyroscope bias needs a "
            "static recording or static pauses"
        )
    pieces, keep, left_out = gyroscope.usable_static_segments(pieces)
    times = [x for x, k in zip(times, keep) if k]
    bias = gyroscope.estimate_bias(pieces)
    artifact = {**plain(bias), **left_out} if left_out["short_left_out"] else plain(bias)
    artifact["source"] = names
    if not figures:
        return artifact, {}
    t = np.concatenate([x[:, 0] for x in times])
    rates = np.vstack(pieces)
    figure = inertial_plots.plot_gyro_bias(t, rates, bias.bias_ls_rad_s)
    return artifact, {"gyr_bias": figure}


def gyr_bias_value(bias: Mapping, estimator: str) -> tuple[np.ndarray, np.ndarray]:
    """The bias (3,) and its std (3,), rad/s.

    Where the static blocks' means scatter beyond the white noise (:func:`gyr_bias_quality`
    flags the axis), the bias wanders and the value at another time differs from the
    recording's mean by that wander: its variance (``wander_var_rad2_s2``) is added.
    """
    if estimator not in ("ls", "mean"):
        raise ValueError(f"gyroscope bias estimator {estimator!r}: expected 'ls' or 'mean'")
    std = np.asarray(bias[f"std_{estimator}_rad_s"], dtype=float)
    quality = gyr_bias_quality(bias)
    flagged = np.array([quality[f"bias_{a}"]["inflation"] > 1 if quality else False for a in AXES])
    wander = np.asarray(bias.get("wander_var_rad2_s2", np.zeros(3)), dtype=float)
    return (
        np.asarray(bias[f"bias_{estimator}_rad_s"], dtype=float),
        np.sqrt(std**2 + np.where(flagged, wander, 0.0)),
    )


def gyr_bias_quality(bias: Mapping) -> dict[str, dict]:
    """Per axis (key ``bias_x``...) the goodness of fit of the static blocks' means; empty for
    a single block (nothing to compare it with)."""
    dof = int(bias.get("dof_blocks", 0))
    if dof < 1:
        return {}
    return {
        f"bias_{a}": {
            **uncertainty.goodness_of_fit(c, dof).to_dict(),
            "rule": "when chi2 > the 0.999 quantile: the variance of the block means beyond the "
            "white noise (the bias's wander) is added to the bias's variance",
        }
        for a, c in zip(AXES, bias["chi2_blocks"], strict=True)
    }


def align_gyr(
    rotation3d_lowpass: pd.DataFrame,
    segments: pd.DataFrame,
    bias: np.ndarray,
    upper: np.ndarray | None = None,
    *,
    method: str = "full",
    exact: bool = True,
    with_covariance: bool = True,
) -> dict:
    """``T_R,gyr`` from the low-pass filtered rotation3d phases (eqs. 28-31), both methods.

    Parameters
    ----------
    bias : ndarray, shape (3,)
        Gyroscope bias, rad/s.
    upper : ndarray, shape (3, 3), optional
        ``S'_gyr`` from the rate table; the identity (unit scale) without one.
    with_covariance : bool
        Measure ``sensitivity`` (``d alpha / d (S', o)``, which :func:`combine_gyr` carries
        into the covariance) and the alignments' covariance for residuals correlated in time;
        without it the artifact has no sensitivity and the plain covariance
        (``correlated=False``), for callers that read fitted values only.
    """
    s = np.eye(3) if upper is None else np.asarray(upper, dtype=float)
    raw = _phases(rotation3d_lowpass, segments, "gyr")
    phases = {label: errormodel.apply(s, bias, values) for label, values in raw.items()}
    alignments = {
        name: align_rotation_axis(phases, method=name, exact=exact, correlated=with_covariance)
        for name in ALIGNMENT_METHODS
    }
    artifact = {"used": method, **{k: a.to_dict() for k, a in alignments.items()}}
    if not with_covariance:
        return artifact
    sensitivity = alignment_sensitivity(
        lambda ph: align_rotation_axis(ph, method=method, exact=exact, correlated=False),
        raw,
        s,
        bias,
    )
    return {
        **artifact,
        "sensitivity": sensitivity.tolist(),
        "sensitivity_to": "upper entries of S' row by row (identity without one), bias",
    }


def _adjacent_static(segments: pd.DataFrame, phase: pd.Series) -> tuple[pd.Series, pd.Series]:
    static = rows_of(segments, "rotation3d", "static")
    before = static[static["end_index"] <= phase.start_index]
    after = static[static["start_index"] >= phase.end_index]
    if before.empty or after.empty:
        raise ValueError(
            f"phase {phase.label!r} of rotation3d ({phase.start_s:.2f}-{phase.end_s:.2f} s) needs "
            "a static pause before and after it for the angle of eq. 36; found "
            f"{len(before)} before and {len(after)} after"
        )
    return before.iloc[-1], after.iloc[0]


def integration_times(table: pd.DataFrame) -> np.ndarray:
    """Strictly increasing sample times of a table's rows, for integrating a rate, s.

    Receive timestamps come in bursts (equal or near-equal stamps, then a pause), which would
    weight samples by the receiver's latency rather than by their sampling interval. With a
    packet counter the times are :func:`imucal.validation.packet_times` (a line through the
    timestamps against the unwrapped counter: jitter averages out, lost packets leave exact
    gaps); without one, strictly increasing timestamps are kept and bursty ones are replaced by
    the least-squares line against the row index (every row a sample, none lost: the only
    assumption left when the logger records no counter).

    Parameters
    ----------
    table : DataFrame
        Rows of one sensor's samples, columns ``t_s`` and optionally ``seq``.

    Returns
    -------
    ndarray, shape (n,)
    """
    from imucal import validation

    t = table[TIME].to_numpy(dtype=float)
    if "seq" in table.columns:
        return validation.packet_times(t, table["seq"].to_numpy())
    if t.size < 2 or np.all(np.diff(t) > 0):
        return t
    period, t0 = np.polyfit(np.arange(t.size, dtype=float), t, 1)
    return t0 + period * np.arange(t.size)


def _pause_angle_variance(before: np.ndarray, after: np.ndarray, axis: str) -> float:
    """Variance of an angle change measured from the pause means (rad^2).

    The angle of a pause mean about ``axis`` moves by the mean's noise across it over its
    projection on the plane: ``var = s_perp^2 / (n |p|^2)`` per pause, with ``s_perp^2`` the
    scatter of the pause's samples across the projection within the plane. A pause that is not
    at rest (the end of a turn inside it) shows as a difference between the angles of its two
    halves: their chi-square against the noise (1 dof) inflates the pause's variance by the
    rule of :func:`imucal.uncertainty.goodness_of_fit`. The two pauses are independent.
    """
    k = AXES.index(axis)
    plane = [(k + 1) % 3, (k + 2) % 3]
    total = 0.0
    for block in (before, after):
        v = block[np.isfinite(block).all(axis=1)][:, plane]
        if len(v) < 4:
            raise ValueError(f"phase {axis!r}: a pause has {len(v)} valid samples, need 4")
        mean = v.mean(axis=0)
        across = np.array([-mean[1], mean[0]]) / np.linalg.norm(mean)
        offset = v @ across / np.linalg.norm(mean)  # angle from the mean's direction, rad
        var = float(np.var(offset, ddof=1)) / len(v)
        halves = np.array_split(offset, 2)
        chi2 = float((halves[0].mean() - halves[1].mean()) ** 2 / (4 * var))
        total += var * uncertainty.goodness_of_fit(chi2, 1).inflation
    return total


def _mean_angle(angles: np.ndarray, variances: np.ndarray) -> tuple[float, float, np.ndarray]:
    """Mean of the angles measured by acc and mag, weighted by their pause noise (rad).

    The variances (:func:`_pause_angle_variance`) differ by far: in phases x and y the
    accelerometer's angle (10 times the samples, half the relative noise) has about 1/40 of
    the magnetometer's variance, so a plain mean would carry a quarter of the magnetometer's,
    and its chi-square ``sum (a_i - mean)^2 / v_i`` would not be chi-square distributed (its
    mean is ``(v_1 + v_2)^2 / (4 v_1 v_2)``, about 10, for 1 dof). With two sensors their
    chi-square about the weighted mean (1 dof) is tested and inflates the variance by the rule
    of :func:`imucal.uncertainty.goodness_of_fit` when they disagree beyond their noise.

    Returns
    -------
    mean, std : float
    weights : ndarray, shape (n_sensors,)
        Of each angle in the mean (sum 1).
    """
    inverse = 1.0 / variances
    weights = inverse / inverse.sum()
    mean = float(weights @ angles)
    var = 1.0 / float(inverse.sum())
    if len(angles) > 1:
        chi2 = float(np.sum((angles - mean) ** 2 * inverse))
        var *= uncertainty.goodness_of_fit(chi2, len(angles) - 1).inflation
    return mean, float(np.sqrt(var)), weights


def _phase_angles(
    rotation3d: pd.DataFrame, segments: pd.DataFrame, measuring: list
) -> dict[str, dict]:
    """Phase label -> the angles of the sensors that measured it, the angle used (their
    weighted mean) with its std (rad), and the gyroscope over the window from the pause before
    to the pause after: its readings (``gyr``, the rows with a rate), their times (``t_s``)
    and the integration weights that give the change of the mean angle as the sensors measured
    it (``weights_s``, :func:`imucal.fits.gyroscope.pause_mean_weights` of each sensor's
    pause samples, by its weight in the mean). Neither depends on the scale or the alignment,
    so both passes of :func:`estimate_gyr_scale` use them."""
    out = {}
    for phase in rows_of(segments, "rotation3d", "phase").itertuples(index=False):
        before, after = _adjacent_static(segments, phase)
        start = int(before.start_index)
        parts = [slice(int(s.start_index), int(s.end_index)) for s in (before, phase, after)]
        angles, angle_var, pauses = {}, {}, []
        for name, cal, cols in measuring:
            vectors = [
                errormodel.apply(cal.matrix, cal.bias, column_values(rotation3d, cols, p))
                for p in parts
            ]
            try:
                angles[name] = gyroscope.measure_angle_change(*vectors, phase.label)
                angle_var[name] = _pause_angle_variance(vectors[0], vectors[2], phase.label)
            except ValueError as err:
                angles[name] = str(err)
                continue
            pauses.append(
                tuple(
                    part.start - start + np.flatnonzero(np.isfinite(v).all(axis=1))
                    for part, v in ((parts[0], vectors[0]), (parts[2], vectors[2]))
                )
            )
        if not angle_var:
            raise ValueError(f"phase {phase.label!r}: no sensor could measure its angle: {angles}")
        angle, std, weights = _mean_angle(
            np.array([angles[n] for n in angle_var]), np.array(list(angle_var.values()))
        )
        window = rotation3d.iloc[start : int(after.end_index)]
        gyr = column_values(window, GYR)
        fresh = np.isfinite(gyr).all(axis=1)  # merged streams: rows of other sensors only
        # a sample on a row without the gyroscope: its angle is that of the last rate row
        rate_row = np.maximum(np.cumsum(fresh) - 1, 0)
        t = integration_times(window[fresh])
        out[phase.label] = {
            "t_s": t,
            "gyr": gyr[fresh],
            "weights_s": sum(
                w * gyroscope.pause_mean_weights(t, rate_row[b], rate_row[a])
                for (b, a), w in zip(pauses, weights, strict=True)
            ),
            "angles_rad": angles,
            "angle_rad": angle,
            "angle_std_rad": std,
        }
    missing = [a for a in AXES if a not in out]
    if missing:
        raise ValueError(f"eq. 36 needs the phases x, y, z of rotation3d; missing {missing}")
    return out


def _phase_scales(
    angles: Mapping[str, dict],
    o: np.ndarray,
    rotation: np.ndarray,
    scale: np.ndarray,
    noise: np.ndarray,
) -> dict[str, dict]:
    """Eq. 36 per phase with the rate ``T_R diag(scale / scale_k) (w - o)``, k the phase axis.

    The other axes' sensitivities enter the phase axis' rate through ``T_R``'s off-diagonal
    entries; weighting them by their scale relative to this axis' makes the ratio of angle to
    integral this axis' scale (eq. 36 takes them all as equal, ``scale`` = 1). The rate is
    integrated with the weights of :func:`_phase_angles`, to the change of the pauses' mean
    angle."""
    per_phase = {}
    for label, phase in angles.items():
        k = AXES.index(label)
        result = gyroscope.estimate_scale(
            phase["t_s"],
            errormodel.apply(rotation @ np.diag(scale / scale[k]), o, phase["gyr"]),
            label,
            phase["angle_rad"],
            noise_std_rad_s=float(noise[k]),
            angle_std_rad=phase["angle_std_rad"],
            weights=phase["weights_s"],
        )
        per_phase[label] = {"angles_rad": phase["angles_rad"], **plain(result)}
    return per_phase


def estimate_gyr_scale(
    rotation3d: pd.DataFrame,
    rotation3d_lowpass: pd.DataFrame,
    segments: pd.DataFrame,
    bias: Mapping,
    alignment: Mapping,
    acc: Mapping | None,
    mag: Mapping | None,
    *,
    bias_estimator: str = "ls",
    with_covariance: bool = True,
) -> dict:
    """Gyroscope scale without tools (eq. 36) after the alignment, and ``T_R,gyr`` at that scale.

    The rotation angle of each phase is measured from the calibrated magnetometer (all phases)
    and accelerometer (phases with a horizontal axis) between the static pauses before and
    after the phase, unwrapped through the phase; where both measure it, their mean weighted
    by their pause noise is used.
    The gyroscope rate, bias-free and aligned with ``T_R,gyr``, is integrated on the timestamps
    over the same window, to the change of the pauses' mean angle: a pause may hold the slow end
    of a turn (the z phase's pause before it ends the transition about z), whose rotation an
    integral from the window's first to its last row would count in full and the pause means
    only in part.

    The paper's order, alignment before scale, aligns the rates at unit scale. With unequal
    scales the rate of a phase about axis k is not along any one direction that a rotation can
    turn onto k for all three phases at once: the alignment is off by about ``alpha`` times
    the scales' relative spread, and the integral of the phase axis' rate takes the other
    axes' sensitivity as this one's (an error of ``alpha^2`` times the spread, 1e-4 for 2 deg
    and 10 %, as large as the noise). So the scale is measured twice: first as the paper does,
    then with ``T_R,gyr`` refitted to ``diag(scale) (w - o)`` (the alignment stage's method
    and form) and the other axes' rates weighted by their scale. The second pass is
    exact to first order in the first pass's error.

    Parameters
    ----------
    rotation3d : DataFrame
        Ingested rotation3d recording.
    rotation3d_lowpass : DataFrame
        The low-pass filtered rotation3d recording (the alignment's input).
    bias, alignment : dict
        Artifacts of the bias and alignment (unit scale) stages.
    acc, mag : dict or None
        Artifacts of the accelerometer and magnetometer stages (``calibration`` key); None (or a
        recording without the sensor's columns) leaves that sensor out of the angle measurement.
    with_covariance : bool
        As for :func:`align_gyr` (the refitted alignment's sensitivity and covariance).

    Returns
    -------
    dict
        Per phase the angles, integrated angle and scale; ``scale`` (3,), ``std_scale`` (3,);
        ``first_pass_scale`` (3,), the paper's (at the unit-scale alignment); ``alignment``,
        the :func:`align_gyr` artifact refitted at ``first_pass_scale``, which the tool-free
        calibration uses.
    """
    o, _ = gyr_bias_value(bias, bias_estimator)
    measuring = [
        (name, SensorCalibration.from_dict(name, artifact["calibration"]), cols)
        for name, artifact, cols in (("mag", mag, MAG), ("acc", acc, ACC))
        if artifact is not None and all(c in rotation3d.columns for c in cols)
    ]
    if not measuring:
        raise ValueError("eq. 36 needs a calibrated magnetometer or accelerometer; got neither")
    noise = np.asarray(bias["noise_std_rad_s"], dtype=float)
    phases = rows_of(segments, "rotation3d", "phase")
    gyr = column_values(rotation3d, GYR)
    clipped = [
        r.label
        for r in phases.itertuples()
        if is_clipped(gyr, int(r.start_index), int(r.end_index))
    ]
    if clipped:
        raise ValueError(
            f"eq. 36 needs the whole rotation of each phase in the gyroscope; phase(s) {clipped} "
            "are clipped at its range (the integrated angle is only a lower bound)"
        )
    angles = _phase_angles(rotation3d, segments, measuring)
    chosen = alignment[alignment["used"]]
    unit = _phase_scales(angles, o, np.asarray(chosen["matrix"], dtype=float), np.ones(3), noise)
    first_pass = np.array([unit[a]["scale"] for a in AXES])
    refit = align_gyr(
        rotation3d_lowpass,
        segments,
        o,
        np.diag(first_pass),
        method=alignment["used"],
        exact=bool(chosen["exact"]),
        with_covariance=with_covariance,
    )
    rotation = np.asarray(refit[refit["used"]]["matrix"], dtype=float)
    per_phase = _phase_scales(angles, o, rotation, first_pass, noise)
    return {
        "per_phase": per_phase,
        "scale": [per_phase[a]["scale"] for a in AXES],
        "std_scale": [per_phase[a]["std"] for a in AXES],
        "first_pass_scale": first_pass.tolist(),
        "alignment": refit,
    }


def fit_gyr_table(
    ratetable: pd.DataFrame,
    segments: pd.DataFrame,
    *,
    saturation_limit_rad_s: float,
    figures: bool = True,
) -> tuple[dict, dict[str, Figure]]:
    """Rate-table step 1 (eq. 33, vector form): full matrix and bias from the run means.

    Runs with saturated samples are left out with a warning; the fit is refused (by
    :func:`imucal.fits.ratetable.fit_rate_table`) only when too few runs remain. ``figures``
    False skips the figure (the in-process chain does not need it).

    Returns
    -------
    artifact : dict
        The fit (``matrix`` K, ``bias``, ``upper`` = S'_gyr, std, per-run errors, warnings).
    figures : dict of str to Figure
        'gyr_table': magnitude errors per run before/after (paper Fig. 15).
    """
    from imucal.plots import inertial as inertial_plots

    rows = rows_of(segments, "ratetable", "run")
    if rows.empty:
        raise ValueError("no rate-table run was segmented (the segmentation notes say why)")
    runs = cut(ratetable, rows, GYR)
    keep, warnings = [], []
    for label, run in zip(rows["label"], runs, strict=True):
        n_sat = int(_saturated(run, saturation_limit_rad_s).sum())
        if n_sat:
            warnings.append(f"rate-table run {label}: {n_sat} saturated samples, run left out")
        keep.append(n_sat == 0)
    keep = np.array(keep, dtype=bool)
    rows = rows[keep]
    runs = [r for r, k in zip(runs, keep, strict=True) if k]
    unit = {a: np.eye(3)[i] for i, a in enumerate(AXES)}
    rates = np.array([np.radians(r.rate_dps) * unit[r.axis] for r in rows.itertuples(index=False)])
    fit = fit_rate_table(
        np.array([r.mean(axis=0) for r in runs]), rates, np.array([len(r) for r in runs])
    )
    # the runs' ends are where a segmentation can take in the ramps: the fit on runs without
    # their outer tenths shows how far that moves (K, b), a systematic term of the covariance
    inner = [r[len(r) // 10 : len(r) - len(r) // 10] for r in runs]
    trimmed = fit_rate_table(
        np.array([r.mean(axis=0) for r in inner]), rates, np.array([len(r) for r in inner])
    )
    # the bound for the runs' own sample noise (pooled about each run's mean): how far the
    # covariance from the residuals about the fit lies above the noise-limited one
    within = np.sqrt(
        sum(np.sum((r - r.mean(axis=0)) ** 2, axis=0) for r in runs) / sum(len(r) - 1 for r in runs)
    )
    crlb = rate_table_crlb(fit.matrix, rates, np.array([len(r) for r in runs]), within)
    artifact = plain(fit)
    artifact.update(
        std_over_crlb=(np.sqrt(np.diag(fit.covariance)) / np.sqrt(np.diag(crlb))).tolist(),
        labels=list(rows["label"]),
        rates_rad_s=rates.tolist(),
        warnings=warnings,
        cut_shift=np.concatenate(
            [(trimmed.matrix - fit.matrix).ravel(), trimmed.bias - fit.bias]
        ).tolist(),
    )
    if not figures:
        return artifact, {}
    figure = inertial_plots.plot_rate_table_errors(fit, list(rows["label"]))
    return artifact, {"gyr_table": figure}


def _truth_rows(truth: Mapping | None) -> tuple[dict, dict]:
    if not truth or "gyr" not in truth:
        return {}, {}
    scale = errormodel.decompose(np.asarray(truth["gyr"]["matrix"], dtype=float)).scale
    return {"truth": tuple(truth["gyr"]["bias"])}, {"truth": tuple(scale)}


def _tool_free_covariance(
    scale: Mapping, o: np.ndarray, o_std: np.ndarray, exact: bool
) -> np.ndarray:
    """Covariance of the tool-free gyroscope calibration ``T_R diag(s)``, ``o``, (21, 21).

    A two-step calibration whose step 1 is ``(diag(s), o)``, ``s`` and ``o`` independent, and
    whose step 2 is the alignment at eq. 36's scale (``scale['alignment']``, its sensitivity to
    ``diag(s)`` and ``o``); ``T_N`` is not observable and taken as exact (xi = 0)."""
    alignment = scale["alignment"]
    chosen = alignment[alignment["used"]]
    step1 = np.zeros((9, 9))
    step1[[0, 3, 5], [0, 3, 5]] = np.square(np.asarray(scale["std_scale"], dtype=float))
    step1[6:, 6:] = np.diag(np.square(o_std))
    covariance = uncertainty.two_step_covariance(
        np.diag(scale["scale"]),
        o,
        step1,
        np.asarray(chosen["alpha_rad"], dtype=float),
        np.asarray(chosen["covariance"], dtype=float),
        np.asarray(alignment["sensitivity"], dtype=float),
        exact,
    )
    xi = uncertainty.GROUPS["xi_rad"]
    covariance[xi, :] = 0.0
    covariance[:, xi] = 0.0
    return covariance


def _table_covariance(table: Mapping, table_alignment: Mapping, exact: bool) -> np.ndarray:
    """Covariance of the rate-table gyroscope calibration ``T_R S'``, ``b``, (21, 21)."""
    chosen = table_alignment[table_alignment["used"]]
    return uncertainty.two_step_covariance(
        np.asarray(table["upper"], dtype=float),
        np.asarray(table["bias"], dtype=float),
        upper_bias_covariance(
            table["matrix"],
            np.asarray(table["covariance"], dtype=float)
            + np.outer(table.get("cut_shift", np.zeros(12)), table.get("cut_shift", np.zeros(12))),
        ),
        np.asarray(chosen["alpha_rad"], dtype=float),
        np.asarray(chosen["covariance"], dtype=float),
        np.asarray(table_alignment["sensitivity"], dtype=float),
        exact,
    )


def tool_free_gyr(
    bias: Mapping,
    scale: Mapping,
    *,
    bias_estimator: str = "ls",
    exact: bool = True,
    with_covariance: bool = True,
) -> SensorCalibration:
    """The gyroscope calibration without tools: ``T_R,gyr diag(scale)`` and the bias.

    ``T_R,gyr`` is the alignment at eq. 36's scale (``scale['alignment']``,
    :func:`estimate_gyr_scale`); ``T_N,gyr`` is not observable and taken as the identity.
    Without ``with_covariance`` the calibration has no covariance and no std.

    Parameters
    ----------
    bias, scale : dict
        Artifacts of the bias stage and of :func:`estimate_gyr_scale`.
    bias_estimator : {'ls', 'mean'}
    exact : bool
        Exact rotation or the paper's small-angle form (eq. 5), as the alignment was fitted.
    with_covariance : bool

    Returns
    -------
    SensorCalibration
    """
    o, o_std = gyr_bias_value(bias, bias_estimator)
    alignment = scale["alignment"]
    alpha = np.asarray(alignment[alignment["used"]]["alpha_rad"], dtype=float)
    covariance = _tool_free_covariance(scale, o, o_std, exact) if with_covariance else None
    return SensorCalibration(
        "gyr",
        o,
        errormodel.compose(scale["scale"], np.zeros(3), alpha, exact=exact),
        "rad/s",
        uncertainty.std_of(covariance),
        f"bias: {bias_estimator} (eqs. 34-35); alignment: {alignment['used']} (eqs. 28-31) "
        "at eq. 36's scale; scale: eq. 36 from acc/mag angles",
        covariance,
        {
            "alignment": {"rule": ALIGNMENT_RULE},
            **gyr_bias_quality(bias),
            "tool_free": {"rule": TOOL_FREE_RULE},
        },
    )


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
        covariance = _table_covariance(table, table_alignment, exact) if with_covariance else None
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

    Every term of the calibration's model is used (:meth:`ImuCalibration.calibrate`); a
    temperature term takes the recording's temperature column (rows without a reading
    interpolated in time). With ``parameter_std`` the table gains, per calibrated column, the
    standard deviation that the calibration's parameter covariance gives the sample
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
        With ``calibrated`` = True, and ``model_terms`` (the terms used) and
        ``temperature_outside_span`` (per sensor, the fraction of samples outside the
        calibrated span but within its margin, and the farthest distance in K) when the model
        has terms.

    Raises
    ------
    ValueError
        If the recording is already calibrated, a sensor is in another unit than the
        calibration expects, the model has a temperature term and the recording has no
        temperature column or is farther outside the calibrated span than its margin, or the
        model has a lever arm and the recording has no gyroscope reading.
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
    temp = _temperature_per_sample(table, source) if calibration.terms.temperature else None
    t_s = table[TIME].to_numpy(dtype=float) if calibration.terms.lever_arm is not None else None
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
    if not calibration.terms.empty:
        meta["model_terms"] = calibration.terms.names()
    if "temperature" in flags:
        meta["temperature_outside_span"] = flags["temperature"]
        for sensor, f in flags["temperature"].items():
            if f["outside_fraction"] > 0:
                logger.warning(
                    "%s: %.1f %% of the samples are outside the %s calibration's temperature "
                    "span (up to %.2f K, within the margin): extrapolated",
                    source, 100 * f["outside_fraction"], sensor, f["max_outside_k"],
                )  # fmt: skip
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


def fit_mag_step1(
    rotation3d: pd.DataFrame,
    cube: pd.DataFrame | None = None,
    *,
    field_norm: float = 1.0,
    refine_lm: bool = True,
) -> dict:
    """Magnetometer step 1 (eqs. 17-24): ellipsoid fit to the rotation3d magnetometer samples.

    The cube's samples, when given, are offered for coverage and join only if they were
    recorded in the same field (see :func:`imucal.fits.magnetometer.fit_ellipsoid`).
    """
    from imucal.fits import magnetometer

    _, samples = magnetometer.field_samples(rotation3d)
    extra = None if cube is None else {"cube": magnetometer.field_samples(cube)[1]}
    fit = magnetometer.fit_ellipsoid(
        samples, refine_lm=refine_lm, field_norm=field_norm, extra_samples=extra
    )
    return fit.to_dict()


def align_mag(
    rotation3d: pd.DataFrame,
    segments: pd.DataFrame,
    step1: Mapping,
    *,
    method: str = "full",
    exact: bool = True,
    with_covariance: bool = True,
) -> dict:
    """Magnetometer step 2 (eqs. 25-27): ``T_R,mag`` from the rotation3d phases, both methods;
    ``with_covariance`` as :func:`imucal.fits.magnetometer.calibrate_alignment`."""
    from imucal.fits import magnetometer

    fit = magnetometer.EllipsoidFit.from_dict(dict(step1))
    phases = {
        label: values[np.all(np.isfinite(values), axis=1)]
        for label, values in _phases(rotation3d, segments, "mag").items()
    }
    result = magnetometer.calibrate_alignment(
        fit, phases, method=method, exact=exact, with_covariance=with_covariance
    )
    artifact = result.to_dict()
    artifact["warnings"] = [
        *step1.get("warnings", []),
        *bound_warnings("mag_step2", "mag", artifact["calibration"]),
    ]
    return artifact
