"""The gyroscope scale without tools (the paper's eq. 36): the integration times of the phases,
the angles the accelerometer and the magnetometer see between the pauses, the scale per axis and
the tool-free gyroscope calibration.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd

from imucal import errormodel, uncertainty
from imucal.calibration import SensorCalibration
from imucal.columns import ACC, AXES, GYR, MAG, TIME, column_values
from imucal.fits import gyroscope
from imucal.fits.alignment import ALIGNMENT_RULE
from imucal.pipeline.stages.common import plain
from imucal.pipeline.stages.gyroscope import align_gyr, gyr_bias_quality, gyr_bias_value
from imucal.segments.detector import is_clipped
from imucal.segments.table import rows_of

#: What the tool-free gyroscope's covariance leaves out.
TOOL_FREE_RULE = (
    "T_N is not observable without a rate table and is taken as exact (xi = 0, std 0); eq. 36's "
    "scale std from the integrated noise and the spread of the acc/mag angles"
)


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
