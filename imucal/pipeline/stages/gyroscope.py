"""The gyroscope stages with tools: the bias from the static segments, the alignment on the
rotation3d phases and the rate-table fit.

Each function cuts the segments it needs out of the ingested (or low-pass filtered) tables, calls
the fits of :mod:`imucal.fits.gyroscope`, :mod:`imucal.fits.alignment` and
:mod:`imucal.fits.ratetable` and returns a JSON-ready artifact.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from imucal import errormodel, uncertainty
from imucal.columns import AXES, GYR
from imucal.fits import gyroscope
from imucal.fits.alignment import align_rotation_axis
from imucal.fits.propagation import alignment_sensitivity, upper_bias_covariance
from imucal.fits.ratetable import fit_rate_table, rate_table_crlb
from imucal.pipeline.outcome import NotApplicable
from imucal.pipeline.stages.common import (
    ALIGNMENT_METHODS,
    at_range,
    phase_values,
    plain,
    sensors_of,
)
from imucal.segments.table import cut, cut_finite, rows_of

if TYPE_CHECKING:  # matplotlib is imported by the stages that draw, when they draw
    from matplotlib.figure import Figure

#: How the rate table's covariance is scaled (for the calibration's ``quality``).
RATE_TABLE_RULE = (
    "noise per axis from the runs' residuals about the fit (dof = n_runs - 4), plus the outer "
    "product of the shift of (K, b) when every run loses its outer tenths (cut_shift)"
)


def estimate_gyr_bias(
    tables: Mapping[str, pd.DataFrame], segments: pd.DataFrame, *, figures: bool = True
) -> tuple[dict, dict[str, Figure]]:
    """Gyroscope bias (eqs. 34-35 and the plain mean) from the static recording.

    Without a static recording with gyroscope samples, the rests and poses of the other
    recordings given are used. Rests too short for a slope are left out and counted.

    Parameters
    ----------
    tables : dict of str to DataFrame
        Ingested recordings by name (rad/s); the paper's protocol gives 'static', or
        'rotation3d' and 'cube' without it.
    segments : DataFrame
        Segments table (its ``attrs['notes']`` name the settings that find short rests).
    figures : bool
        Draw the figure (the in-process chain does not need it).

    Returns
    -------
    artifact : dict
        The bias of both estimators with their std, ``source`` (the recordings used) and the
        count of left-out rests when there are any.
    figures : dict of str to Figure
        'gyr_bias': the static rates before and after bias removal (Figs. 16-17).

    Raises
    ------
    NotApplicable
        If no rest has gyroscope samples, or none is long enough.
    """
    from imucal.plots import inertial as inertial_plots

    with_gyr = [r for r in tables if "gyr" in sensors_of(tables[r])]
    names = ["static"] if "static" in with_gyr else with_gyr
    pieces, times = [], []
    for name in names:
        rows = rows_of(segments, name, "static", "position")
        for t, values in cut_finite(tables[name], rows, GYR):
            if len(values) >= 2:
                pieces.append(values)
                times.append(t)
    if not pieces:
        # the segmentation's word on rests too short to count names the settings that find them
        notes = segments.attrs.get("notes", {})
        hints = [n for r, n in notes.items() if r in tables and "still interval" in n]
        raise NotApplicable("; ".join(["no static segment with gyroscope samples", *hints]))
    pieces, keep, left_out = gyroscope.usable_static_segments(pieces)
    if not pieces:
        raise NotApplicable(
            f"no static segment with at least {gyroscope.MIN_STATIC_SAMPLES} gyroscope samples "
            f"({left_out['short_left_out']} shorter ones)"
        )
    times = [x for x, k in zip(times, keep) if k]
    bias = gyroscope.estimate_bias(pieces)
    artifact = {**plain(bias), **left_out} if left_out["short_left_out"] else plain(bias)
    artifact["source"] = names
    if not figures:
        return artifact, {}
    figure = inertial_plots.plot_gyro_bias(
        np.concatenate(times), np.vstack(pieces), bias.bias_ls_rad_s
    )
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
    raw = phase_values(rotation3d_lowpass, segments, "gyr")
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


def fit_gyr_table(
    ratetable: pd.DataFrame,
    segments: pd.DataFrame,
    *,
    saturation_limit_rad_s: float | None,
    figures: bool = True,
) -> tuple[dict, dict[str, Figure]]:
    """Rate-table step 1 (eq. 33, vector form): full matrix and bias from the run means.

    Runs with saturated samples (at ``saturation_limit_rad_s``; None: the range is not known,
    nothing is left out) are left out with a warning; the fit is refused (by
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
    limit = saturation_limit_rad_s
    for label, run in zip(rows["label"], runs, strict=True):
        n_sat = 0 if limit is None else int(at_range(run, limit).sum())
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


def table_covariance(table: Mapping, table_alignment: Mapping, exact: bool) -> np.ndarray:
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
