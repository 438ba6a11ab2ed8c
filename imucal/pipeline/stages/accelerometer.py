"""The accelerometer stages: the cube fit and the alignment on the rotation3d phases, and the
calibration and its quality that the cube gives.

Each function cuts the segments it needs out of the ingested (or low-pass filtered) tables, calls
the fits of :mod:`imucal.fits.accelerometer` and :mod:`imucal.fits.alignment` and returns a
JSON-ready artifact.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from imucal import errormodel, uncertainty
from imucal.calibration import SensorCalibration
from imucal.columns import ACC
from imucal.fits import accelerometer, orientations
from imucal.fits.alignment import ALIGNMENT_RULE, align_constant_component
from imucal.fits.propagation import alignment_sensitivity
from imucal.pipeline.outcome import NotApplicable
from imucal.pipeline.stages.common import ALIGNMENT_METHODS, phase_values, plain, sensors_of
from imucal.segments.table import cut_finite, rows_of
from imucal.validation.plausibility import bound_warnings

if TYPE_CHECKING:  # matplotlib is imported by the stages that draw, when they draw
    from matplotlib.figure import Figure


#: The cube fit has 9 parameters and one equation per position.
MIN_CUBE_POSITIONS = 9
#: Recordings of static poses the cube fit may be run on, preferred first.
POSE_RECORDINGS = ("cube", "poses")


def pose_rows(segments: pd.DataFrame, recording: str) -> pd.DataFrame:
    """The poses of a recording: its segments of kind 'position' (the faces its protocol
    names), else those of kind 'static' (the rests the fallback segmentation finds)."""
    rows = rows_of(segments, recording, "position")
    return rows if not rows.empty else rows_of(segments, recording, "static")


def pose_coverage(table: pd.DataFrame, rows: pd.DataFrame) -> orientations.OrientationCoverage:
    """The distinct gravity directions of a recording's poses (those long enough for the fit)."""
    pieces = [v for _, v in cut_finite(table, rows, ACC)]
    pieces = [v for v in pieces if len(v) >= accelerometer.MIN_SAMPLES_PER_POSITION]
    return orientations.cube_coverage(
        np.array([v.mean(axis=0) for v in pieces]).reshape(-1, 3),
        np.array([len(v) for v in pieces]),
    )


def _pose_recording(tables: Mapping[str, pd.DataFrame], segments: pd.DataFrame) -> str:
    """The first of :data:`POSE_RECORDINGS` with accelerometer samples and enough poses."""
    with_acc = [r for r in POSE_RECORDINGS if r in tables and "acc" in sensors_of(tables[r])]
    for r in with_acc:
        if len(pose_rows(segments, r)) >= MIN_CUBE_POSITIONS:
            return r
    counts = {r: len(pose_rows(segments, r)) for r in POSE_RECORDINGS if r in tables}
    shown = [pose_coverage(tables[r], pose_rows(segments, r)).reason for r in with_acc]
    raise NotApplicable(
        f"needs >= {MIN_CUBE_POSITIONS} static poses in a cube or poses recording with "
        f"accelerometer data (static poses found: {counts or 'no such recording'})"
        + "".join(f"; {reason}" for reason in shown if reason)
        + setting_hints(segments, with_acc)
    )


def setting_hints(segments: pd.DataFrame, recordings: list[str]) -> str:
    """The segmentation's notes on these recordings that name the settings which would find
    more rests (``segmentation.min_static_s``), each after a '; '."""
    notes = segments.attrs.get("notes", {})
    clauses = [c for r in recordings for c in notes.get(r, "").split("; ")]
    return "".join(f"; {c}" for c in clauses if "segmentation.min_static_s" in c)


def fit_acc_cube(
    tables: Mapping[str, pd.DataFrame],
    segments: pd.DataFrame,
    *,
    gravity_m_s2: float,
    saturation_limit_m_s2: float | None,
    method: str = "means",
    figures: bool = True,
) -> tuple[dict, dict[str, Figure]]:
    """Accelerometer step 1 (eq. 32) on the static poses of the cube (or a poses recording).

    The poses (:func:`pose_rows`) of the first of :data:`POSE_RECORDINGS` with at least
    :data:`MIN_CUBE_POSITIONS` of them are fitted when their gravity directions determine the
    9 parameters (:func:`imucal.fits.orientations.cube_coverage`); each pose in turn is also
    predicted by the fit on the others when there are more than the minimum.

    Parameters
    ----------
    tables : dict of str to DataFrame
        Ingested recordings by name (m/s^2); the paper's protocol gives the cube.
    segments : DataFrame
        Segments table (its ``attrs['notes']``, the segmentation's notes, join the artifact).
    gravity_m_s2 : float
    saturation_limit_m_s2 : float or None
        ``range_counts * sensitivity`` of the accelerometer; samples at it are excluded (None:
        the range is unknown, nothing is excluded).
    method : {'means', 'samples'}
        See :func:`imucal.fits.accelerometer.fit_cube`.
    figures : bool
        Draw the figure (the in-process chain does not need it).

    Returns
    -------
    artifact : dict
        The fit (``upper`` = S'_acc, ``bias``, std, per-position residuals before/after,
        warnings), the ``recording`` fitted, its ``orientations``, the held-out errors and the
        ``calibration`` the cube alone gives.
    figures : dict of str to Figure
        'acc_cube': |a| - g per position before/after (paper Fig. 10).

    Raises
    ------
    NotApplicable
        If no recording has enough poses, or their directions do not determine the fit.
    """
    from imucal.plots import inertial as inertial_plots

    recording = _pose_recording(tables, segments)
    rows = pose_rows(segments, recording)
    coverage = pose_coverage(tables[recording], rows)
    if not coverage.identifiable:
        raise NotApplicable(coverage.reason + setting_hints(segments, [recording]))
    positions = [v for _, v in cut_finite(tables[recording], rows, ACC)]
    fit = accelerometer.fit_cube(
        positions,
        gravity_m_s2,
        labels=[str(label) for label in rows["label"]],
        saturation_limit_m_s2=saturation_limit_m_s2,
        method=method,
    )
    artifact = plain(fit)
    artifact.update(gravity_m_s2=gravity_m_s2, recording=recording)
    artifact["orientations"] = coverage.to_dict()
    if len(positions) > MIN_CUBE_POSITIONS:
        held = accelerometer.heldout_errors(positions, gravity_m_s2)
        artifact.update(
            heldout_error_before_m_s2=held.before.tolist(),
            heldout_error_after_m_s2=held.after.tolist(),
            heldout_predicted_std_m_s2=held.predicted_std.tolist(),
        )
    notes = segments.attrs.get("notes", {})
    if recording in notes:  # how the poses were found (e.g. the tremor-adaptive detector)
        artifact["segmentation"] = notes[recording]
    artifact["calibration"] = cube_calibration(artifact).to_dict()
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
    raw = phase_values(rotation3d_lowpass, segments, "acc")
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
