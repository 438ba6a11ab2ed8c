"""The orientation reference in the chain: the gyroscope calibrated against it (stage
``gyr_reference``) and the validation of a session's calibration against it.

Each recording declared with a ``reference`` (motion capture, robot) is aligned in time and
mounting by :mod:`imucal.validation.orientation`. The stage fits the gyroscope
(:mod:`imucal.fits.reference`) on the recordings whose reference is not ``held_out``; the
validation compares, on every recording with a reference, the gyroscope as read, with the bias
only, and calibrated, so a held-out recording tests the calibration on data it has not seen.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation

from imucal import errormodel
from imucal.calibration import SensorCalibration
from imucal.columns import ACC, GYR, MAG, QUAT, TIME
from imucal.fits import magnetometer
from imucal.fits.reference import MAX_ENTRY_STD, fit_gyro_to_reference, fit_mag_to_reference
from imucal.orientation import quat_conjugate, quat_rotate, up_vector
from imucal.pipeline.registry import split_held_out
from imucal.uncertainty import (
    numerical_jacobian,
    std_of,
    two_step_covariance,
    upper_entries,
    upper_matrix,
)
from imucal.validation.orientation import (
    OrientationAlignment,
    align_orientation_reference,
    compare_window_errors,
    field_direction_errors,
    gravity_errors,
    mount_orientation_reference,
    rate_agreement,
    summarise_windows,
    window_errors,
)
from imucal.validation.plausibility import FALLBACK_WINDOWS_S, compare_with_fallback
from imucal.validation.timing import TimeAlignment

#: Format of ``results/{dataset}/reference/validation.json``.
VALIDATION_FORMAT = 1


def _series(table: pd.DataFrame, columns) -> tuple[np.ndarray, np.ndarray]:
    """(t_s, values) of the rows where every column is finite."""
    values = table[list(columns)].to_numpy(dtype=float)
    ok = np.all(np.isfinite(values), axis=1)
    return table[TIME].to_numpy(dtype=float)[ok], values[ok]


def _orientation(reference: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    return reference[TIME].to_numpy(dtype=float), reference[list(QUAT)].to_numpy(dtype=float)


def _window_errors(
    t: np.ndarray,
    gyr: np.ndarray,
    t_ref: np.ndarray,
    quat: np.ndarray,
    alignment: OrientationAlignment,
    calibration: SensorCalibration,
    mounting: np.ndarray | None,
) -> dict:
    """Orientation errors over :data:`~imucal.validation.plausibility.FALLBACK_WINDOWS_S` of a
    gyroscope calibration with its mounting (None: its own on this recording, by Wahba, as the
    validation finds it; a held-out recording may be mounted otherwise)."""
    gyr_b = errormodel.apply(calibration.matrix, calibration.bias, gyr)
    if mounting is None:
        mounting = mount_orientation_reference(
            t, gyr_b, t_ref, quat, alignment.time
        ).mounting.matrix
    return window_errors(t, gyr_b, t_ref, quat, alignment, mounting, FALLBACK_WINDOWS_S)


def fit_gyr_reference(
    tables: Mapping[str, pd.DataFrame],
    references: Mapping[str, tuple[pd.DataFrame, Mapping]],
    rests: tuple[np.ndarray, np.ndarray] | None,
    where: Mapping[str, str],
) -> dict:
    """Stage ``gyr_reference``: the gyroscope calibrated against the orientation references.

    The fit (:func:`imucal.fits.reference.fit_gyro_to_reference`, integrated rotations) runs
    on the recordings whose reference is not held out
    (:func:`imucal.pipeline.registry.split_held_out`). Its fallback is the nominal matrix with
    the bias of the rests (stage ``gyr_bias``, the "bias only" of the validation), or without
    rests the bias fitted against the reference, with the mounting of the same fit with the
    nominal matrix; both integrate the gyroscope over
    :data:`~imucal.validation.plausibility.FALLBACK_WINDOWS_S` windows on the fitted recordings
    and on the held-out ones (:func:`imucal.validation.plausibility.compare_with_fallback`).
    The fitted matrix is shipped only if it does no worse than the fallback on either;
    otherwise the fallback is shipped, with the reason under ``fallback`` and in ``warnings``.
    (The physical bounds are checked after the stage, as for every stage:
    :func:`imucal.validation.plausibility.review_fit`.)

    Parameters
    ----------
    tables : mapping of str to DataFrame
        Ingested recordings by name, the held-out ones included.
    references : mapping of str to (DataFrame, dict)
        Ingested orientation reference (``t_s``, ``q_w..q_z``) and its metadata per recording.
    rests : (ndarray, ndarray) or None
        Gyroscope bias of stage ``gyr_bias`` and its std, shape (3,) each, rad/s: the time
        alignment's and the fit's start, and the fallback's bias (None: without rests, zero;
        the fit finds its own).
    where : mapping of str to str
        Per recording, the key path of its reference in ``dataset.yaml`` (error messages).

    Returns
    -------
    dict
        The shipped fit (:meth:`imucal.fits.reference.ReferenceGyroFit.to_dict`), the
        recordings used, the time alignment and mounting of each (``alignments``), the
        comparison with the fallback (``checks``), and ``fallback`` and ``warnings`` when the
        fitted matrix is not shipped or is undetermined.

    Raises
    ------
    ValueError
        No recording with a reference that is not held out, or the alignment or fit fails (the
        message names the declaration).
    """
    used, held = split_held_out(references)
    if not used:
        raise ValueError(
            f"every orientation reference ({sorted(references)}) is held_out; expected one to "
            "fit on"
        )
    start = np.zeros(3) if rests is None else np.asarray(rests[0], dtype=float)
    series, aligned, alignments = {}, {}, {}
    for name in [*used, *held]:
        t, gyr = _series(tables[name], GYR)
        t_ref, quat = _orientation(references[name][0])
        alignment = align_orientation_reference(t, gyr - start, t_ref, quat, where=where[name])
        series[name] = (t, gyr, t_ref, quat)
        aligned[name] = alignment
        alignments[name] = alignment.to_dict()
    fit_input = [
        (t, gyr, aligned[n].to_module_time(t_ref), quat)
        for n, (t, gyr, t_ref, quat) in series.items()
        if n in used
    ]
    mounting0 = aligned[used[0]].mounting.matrix
    fit = fit_gyro_to_reference(fit_input, mounting0, start)
    nominal = fit_gyro_to_reference(fit_input, mounting0, start, fit_matrix=False)
    if rests is not None:
        nominal = dataclasses.replace(
            nominal,
            calibration=SensorCalibration(
                "gyr", rests[0], np.eye(3), "rad/s", {"bias": rests[1]},
                "bias only (gyr_bias, the rests), nominal matrix; mounting against the reference",
            ),
        )  # fmt: skip
    checks, reasons = {}, []
    for label, names in (("own data", used), ("held-out data", held)):
        if not names:
            continue
        errors = {
            key: [
                _window_errors(
                    *series[n], aligned[n], f.calibration, f.mounting if n in used else None
                )
                for n in names
            ]
            for key, f in (("fitted", fit), ("fallback", nominal))
        }
        test = compare_with_fallback(errors["fitted"], errors["fallback"])
        checks[label] = test
        if test["worse"]:
            reasons.append(
                f"on {label} ({', '.join(names)}) the fitted matrix integrates to a larger "
                f"orientation error over {FALLBACK_WINDOWS_S[0]:g} s windows than its fallback "
                f"(median {test['fitted']['median_deg']:.3g} against "
                f"{test['fallback']['median_deg']:.3g} deg, RMS {test['fitted']['rms_deg']:.3g} "
                f"against {test['fallback']['rms_deg']:.3g} deg)"
            )
    shipped = nominal if reasons else fit
    out = {
        **shipped.to_dict(),
        "recordings": used,
        "held_out": held,
        "alignments": alignments,
        "checks": checks,
    }
    warnings = []
    if fit.held_nominal and not reasons:
        warnings.append(
            f"gyr_reference: the motion does not determine {', '.join(fit.held_nominal)} to "
            f"{MAX_ENTRY_STD:g} (std {_held_std(fit)}): held at the nominal value"
        )
    if reasons:
        out["fallback"] = {
            "shipped": "the nominal matrix with "
            + ("the rests' bias" if rests is not None else "the bias fitted against the reference"),
            "reason": "; ".join(reasons),
            "fitted": fit.to_dict(),
        }
        warnings = [
            f"gyr_reference: the fitted matrix is not shipped, {out['fallback']['shipped']} is: "
            f"{out['fallback']['reason']}"
        ]
    if warnings:
        out["warnings"] = warnings
    return out


def _held_std(fit) -> str:
    from imucal.fits.reference import ENTRY_NAMES

    flat = [fit.std_matrix[i, j] for i, j in ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))]
    return ", ".join(
        f"{name} {std:.2g}" for name, std in zip(ENTRY_NAMES, flat) if name in fit.held_nominal
    )


def _module_time(time: Mapping, t_reference: np.ndarray) -> np.ndarray:
    """Module-clock times of reference times, from a time alignment's dict form."""
    return (np.asarray(t_reference, dtype=float) - time["offset_s"]) / (
        1.0 + time["drift_ppm"] * 1e-6
    )


def rest_directions(
    table: pd.DataFrame,
    reference: pd.DataFrame,
    rests: pd.DataFrame,
    time: Mapping,
    mounting: np.ndarray,
    up: str,
) -> tuple[list[np.ndarray], np.ndarray, list[str]]:
    """Accelerometer samples of each rest and the reference's up direction there, in B.

    Parameters
    ----------
    table : DataFrame
        Ingested recording.
    reference : DataFrame
        Its ingested orientation reference.
    rests : DataFrame
        The recording's static segments (segments-table rows).
    time : mapping
        The clock (:meth:`imucal.validation.timing.TimeAlignment.to_dict`).
    mounting : array_like, shape (3, 3)
        Reference body -> B.
    up : str
        The reference world's up axis (``+z``...).

    Returns
    -------
    positions : list of ndarray, shape (n_k, 3)
        Accelerometer readings of each rest with reference samples, m/s^2.
    directions : ndarray, shape (k, 3)
        Unit up direction in B per rest (mean over the rest's present reference samples).
    labels : list of str
    """
    t_ref, quat = _orientation(reference)
    t_ref_m = _module_time(time, t_ref)
    present = np.all(np.isfinite(quat), axis=1)
    up_world = up_vector(up)
    t, acc = _series(table, ACC)
    positions, directions, labels = [], [], []
    for row in rests.itertuples(index=False):
        sel_r = present & (t_ref_m >= row.start_s) & (t_ref_m <= row.end_s)
        sel_m = (t >= row.start_s) & (t <= row.end_s)
        if np.count_nonzero(sel_r) < 2 or np.count_nonzero(sel_m) < 2:
            continue
        body = quat_rotate(quat_conjugate(quat[sel_r]), up_world).mean(axis=0)
        direction = np.asarray(mounting, dtype=float) @ body
        positions.append(acc[sel_m])
        directions.append(direction / np.linalg.norm(direction))
        labels.append(str(row.label))
    return positions, np.array(directions).reshape(-1, 3), labels


def fit_acc_reference(
    tables: Mapping[str, pd.DataFrame],
    references: Mapping[str, tuple[pd.DataFrame, Mapping]],
    segments: pd.DataFrame,
    gyr_reference: Mapping,
    gravity_m_s2: float,
) -> dict:
    """Stage ``acc_reference``: the accelerometer from the reference's gravity direction at rests.

    The rests of the recordings the gyroscope was fitted on (``gyr_reference``) are positions
    of known orientation: the reference's up direction, carried into frame B of the gyroscope by
    the fitted mounting, so both sensors end in the same B. The known-orientation fit
    (:func:`imucal.fits.ferraris.fit_known_orientations`) needs at least four rests whose
    directions span 3-D.

    Returns
    -------
    dict
        The fit (as the Ferraris stage writes it) with ``recordings`` and ``gravity_m_s2``.

    Raises
    ------
    ValueError
        Too few rests with reference samples, or directions that do not span 3-D.
    """
    from imucal.fits.ferraris import fit_known_orientations

    mounting = np.asarray(gyr_reference["mounting"]["matrix"], dtype=float)
    positions, directions, labels = [], [], []
    for name in gyr_reference["recordings"]:
        rests = segments[
            (segments["recording"] == name) & segments["kind"].isin(["static", "position"])
        ]
        reference, meta = references[name]
        pos, dirs, labs = rest_directions(
            tables[name], reference, rests, gyr_reference["alignments"][name]["time"],
            mounting, meta["up"],
        )  # fmt: skip
        positions += pos
        directions.append(dirs)
        labels += [f"{name}:{label}" for label in labs]
    fit = fit_known_orientations(positions, np.vstack(directions), gravity_m_s2, labels=labels)
    artifact = {k: v for k, v in _plain(fit).items() if k != "calibration"}
    artifact.update(
        calibration=fit.calibration.to_dict(),
        gravity_m_s2=gravity_m_s2,
        recordings=list(gyr_reference["recordings"]),
    )
    return artifact


def fit_mag_reference(
    tables: Mapping[str, pd.DataFrame],
    references: Mapping[str, tuple[pd.DataFrame, Mapping]],
    step1: Mapping,
    gyr_reference: Mapping,
) -> dict:
    """Stage ``mag_reference``: the magnetometer's alignment to B from the orientation reference.

    On the recordings the gyroscope was fitted on (``gyr_reference``, their clocks and the
    fitted mounting), the ellipsoid-fitted magnetometer (``mag_step1``) at each present reference
    sample is aligned so that the field is one direction in the reference's world
    (:func:`imucal.fits.reference.fit_mag_to_reference`). The calibration is step 1's with
    ``T_R``; its covariance joins step 1's, the alignment's own (jackknife), the mounting's (B
    is where the magnetometer is aligned to) and the alignment's dependence on step 1
    (``d alpha / d theta`` by refitting with each step-1 parameter moved).

    Returns
    -------
    dict
        The fit (:meth:`~imucal.fits.reference.ReferenceMagFit.to_dict`), ``calibration``,
        ``recordings``.

    Raises
    ------
    ValueError
        No fitted recording has magnetometer samples, or the fit's own refusals.
    """
    step = magnetometer.EllipsoidFit.from_dict(dict(step1))
    mounting = Rotation.from_matrix(np.asarray(gyr_reference["mounting"]["matrix"], dtype=float))
    raw, frames, used = [], [], []
    for name in gyr_reference["recordings"]:
        if not set(MAG) <= set(tables[name].columns):
            continue
        t, mag = _series(tables[name], MAG)
        if len(t) < 2:
            continue
        t_ref, quat = _orientation(references[name][0])
        tau = _module_time(gyr_reference["alignments"][name]["time"], t_ref)
        keep = np.all(np.isfinite(quat), axis=1) & (tau >= t[0]) & (tau <= t[-1])
        raw.append(np.column_stack([np.interp(tau[keep], t, mag[:, k]) for k in range(3)]))
        # B -> world: the reference body -> world after B -> reference body (M^T)
        body = Rotation.from_quat(quat[keep][:, [1, 2, 3, 0]])
        frames.append(body * mounting.inv())
        used.append(name)
    if not used:
        raise ValueError("no recording fitted against the reference has magnetometer samples")
    samples = np.vstack(raw)
    to_world = Rotation.concatenate(frames)
    # at most 20,000 samples, evenly: the neighbours of a 100 Hz+ reference say the same
    pick = np.unique(np.linspace(0, len(samples) - 1, min(len(samples), 20000)).astype(int))
    samples, to_world = samples[pick], to_world[pick]

    frame = np.diag(np.asarray(gyr_reference["mounting"]["std_rad"], dtype=float) ** 2)

    def fitted(theta: np.ndarray):
        field = (samples - theta[6:9]) @ upper_matrix(theta[:6]).T
        return fit_mag_to_reference(field, to_world, frame)

    theta = np.concatenate([upper_entries(step.upper), step.bias])
    fit = fitted(theta)
    sensitivity = numerical_jacobian(lambda x: fitted(x).alpha_rad, theta, rel_step=1e-4)
    covariance = two_step_covariance(
        step.upper, step.bias, step.selected.covariance, fit.alpha_rad, fit.alpha_covariance,
        sensitivity,
    )  # fmt: skip
    calibration = SensorCalibration(
        "mag",
        step.bias,
        Rotation.from_rotvec(fit.alpha_rad).as_matrix() @ step.upper,
        "normalised",
        std_of(covariance),
        "ellipsoid fit and T_R against the orientation reference (B of gyr_reference)",
        covariance,
    )
    return {**fit.to_dict(), "calibration": calibration.to_dict(), "recordings": used}


def _plain(fit) -> dict:
    from imucal.pipeline.stages import plain

    return plain(fit)


def _variant(
    label: str,
    t: np.ndarray,
    gyr_b: np.ndarray,
    t_ref: np.ndarray,
    quat: np.ndarray,
    time: TimeAlignment,
    where: str,
    windows_s: Sequence[float],
) -> tuple[dict, OrientationAlignment, dict]:
    alignment = mount_orientation_reference(t, gyr_b, t_ref, quat, time, where=where)
    mounting = alignment.mounting.matrix
    windows = window_errors(t, gyr_b, t_ref, quat, alignment, mounting, windows_s)
    out = {
        "gyroscope": label,
        "mounting": alignment.mounting.to_dict(),
        "rates": rate_agreement(t, gyr_b, t_ref, quat, alignment, mounting),
        "orientation": summarise_windows(windows, windows_s),
    }
    return out, alignment, windows


def _transfer(name: str, windows: Mapping[str, dict], windows_s: Sequence[float]) -> dict:
    """The calibrated gyroscope against the bias-only one on a held-out recording, per window.

    The criterion is fixed before the data are seen: a paired test over independent windows
    (:func:`imucal.validation.orientation.compare_window_errors`). A calibration that does worse
    than its own bias on data it was not fitted on gets a warning: its scale and axes do not
    carry over (a rate-dependent scale, a reference that lags fast motion, a different mount).
    """
    out: dict = {"windows": {}, "warnings": []}
    for window in windows_s:
        key = f"{window:g}s"
        test = compare_window_errors(
            windows["calibrated"][key], windows["bias"][key], float(window)
        )
        out["windows"][key] = test
        if test["verdict"] == "worse":
            out["warnings"].append(
                f"held-out recording {name}: the calibrated gyroscope integrates to a larger "
                f"orientation error over {key} windows than the bias-only gyroscope (median "
                f"difference {test['median_difference_deg']:+.3g} deg over "
                f"{test['n_windows']} independent windows, Wilcoxon p = {test['p_value']:.2g}): "
                "its scale, non-orthogonality and axes do not carry over to this recording"
            )
    return out


def _field_directions(
    table: pd.DataFrame,
    calibration: Mapping,
    t_ref: np.ndarray,
    quat: np.ndarray,
    alignments: Mapping[str, OrientationAlignment],
    up: str,
) -> dict:
    """Field direction in the reference's world: the magnetometer as read and calibrated.

    The magnetometer as read is carried into the world with the mounting of the gyroscope as
    read (its axes are nominally those of the gyroscope); the calibrated one, which is in frame
    B after step 2, with the mounting of the calibrated (else bias-corrected) gyroscope.
    """
    t, mag = _series(table, MAG)
    raw = alignments["raw"]
    out = {"raw": field_direction_errors(t, mag, t_ref, quat, raw, raw.mounting.matrix, up)}
    if "mag" in calibration:
        cal = SensorCalibration.from_dict("mag", calibration["mag"])
        best = alignments.get("calibrated", alignments.get("bias", raw))
        out["calibrated"] = field_direction_errors(
            t, errormodel.apply(cal.matrix, cal.bias, mag), t_ref, quat, best,
            best.mounting.matrix, up,
        )  # fmt: skip
        before, after = out["raw"]["median_deg"], out["calibrated"]["median_deg"]
        if before is not None and after is not None and after > before:
            out["warnings"] = [
                f"the calibrated magnetometer's field direction scatters more about its mean "
                f"than the magnetometer as read (median {after:.3g} deg against {before:.3g} "
                "deg): its calibration does not make the field constant in the reference's "
                "world on this recording"
            ]
    return out


def validate_references(
    tables: Mapping[str, pd.DataFrame],
    references: Mapping[str, tuple[pd.DataFrame, Mapping]],
    segments: pd.DataFrame,
    calibration: Mapping,
    bias_rad_s: np.ndarray | None,
    where: Mapping[str, str],
    windows_s: Sequence[float],
) -> dict:
    """The session's calibration against its orientation references, recording by recording.

    Parameters
    ----------
    tables, references, where
        As in :func:`fit_gyr_reference`.
    segments : DataFrame
        The segments table; the ``static`` and ``position`` segments of a recording are its
        rests (gravity direction).
    calibration : mapping
        ``calibration.json`` of the session (sensors it could not calibrate under ``missing``).
    bias_rad_s : array_like, shape (3,), or None
        The gyroscope bias of stage ``gyr_bias`` (the "bias only" comparison), None without.
    windows_s : sequence of float
        Windows of the integrated-orientation comparison, s (config ``reference.windows_s``).

    Returns
    -------
    dict
        ``format``, ``gyroscope_method``, ``summary`` (per recording: held out, offset, drift,
        mounting angle, orientation error medians per window and gyroscope) and
        ``recordings`` (per recording: ``alignment`` of the raw gyroscope and per gyroscope
        ``raw``, ``bias`` and ``calibrated`` the mounting, per-axis rates and windowed
        orientation errors; ``gravity`` at rests for the accelerometer as read and calibrated;
        ``field``, the magnetometer's direction in the reference's world as read and
        calibrated; on a held-out recording ``transfer``, the paired test of the calibrated
        gyroscope against the bias-only one per window, with ``warnings`` when it is worse).
        Every gyroscope gets its own mounting (Wahba) on each recording, so the comparison is
        about scale, non-orthogonality and bias, not about the misalignment.

    Raises
    ------
    ValueError
        When a reference cannot be aligned (the message names its declaration).
    """
    gyr_cal = (
        SensorCalibration.from_dict("gyr", calibration["gyr"]) if "gyr" in calibration else None
    )
    acc_cal = (
        SensorCalibration.from_dict("acc", calibration["acc"]) if "acc" in calibration else None
    )
    out: dict = {
        "format": VALIDATION_FORMAT,
        "gyroscope_method": None if gyr_cal is None else gyr_cal.method,
        "accelerometer_method": None if acc_cal is None else acc_cal.method,
        "summary": {},
        "recordings": {},
    }
    for name, (reference, meta) in references.items():
        t, gyr = _series(tables[name], GYR)
        t_ref, quat = _orientation(reference)
        variants = {"raw": gyr}
        if bias_rad_s is not None:
            variants["bias"] = gyr - np.asarray(bias_rad_s, dtype=float)
        if gyr_cal is not None:
            variants["calibrated"] = errormodel.apply(gyr_cal.matrix, gyr_cal.bias, gyr)
        record: dict = {
            "held_out": bool(meta.get("held_out", False)),
            "reference": {k: meta.get(k) for k in ("rows", "gap_rows", "orientation", "up")},
        }
        # the clock from the bias-corrected gyroscope (else as read), shared by all three
        clock = align_orientation_reference(
            t, variants.get("bias", gyr), t_ref, quat, where=where[name]
        ).time
        alignments, windows = {}, {}
        for label, values in variants.items():
            record[label], alignments[label], windows[label] = _variant(
                label, t, values, t_ref, quat, clock, where[name], windows_s
            )
        if record["held_out"] and {"bias", "calibrated"} <= set(windows):
            record["transfer"] = _transfer(name, windows, windows_s)
        base = alignments.get("bias", alignments["raw"])
        record["alignment"] = base.to_dict()
        if "mag_x" in tables[name].columns:
            record["field"] = _field_directions(
                tables[name], calibration, t_ref, quat, alignments, meta["up"]
            )
        rests = segments[
            (segments["recording"] == name) & segments["kind"].isin(["static", "position"])
        ]
        if "acc_x" in tables[name].columns and len(rests):
            t_acc, acc = _series(tables[name], ACC)
            spans = list(zip(rests["start_s"].astype(float), rests["end_s"].astype(float)))
            record["gravity"] = {
                "raw": gravity_errors(
                    t_acc, acc, spans, t_ref, quat, base, base.mounting.matrix, meta["up"]
                )
            }
            if acc_cal is not None:
                best = alignments.get("calibrated", base)
                record["gravity"]["calibrated"] = gravity_errors(
                    t_acc,
                    errormodel.apply(acc_cal.matrix, acc_cal.bias, acc),
                    spans,
                    t_ref,
                    quat,
                    best,
                    best.mounting.matrix,
                    meta["up"],
                )
        out["recordings"][name] = record
        out["summary"][name] = {
            "held_out": record["held_out"],
            **(
                {"transfer": {k: v["verdict"] for k, v in record["transfer"]["windows"].items()}}
                if "transfer" in record
                else {}
            ),
            "offset_ms": 1e3 * base.time.offset_s,
            "offset_std_ms": 1e3 * base.time.offset_std_s,
            "drift_ppm": base.time.drift_ppm,
            "mounting_deg": base.mounting.angle_deg,
            "reference_period_ms": 1e3 * base.reference_period_s,
            **{
                f"orientation_median_deg_{window}": {
                    label: record[label]["orientation"][window]["median_deg"] for label in variants
                }
                for window in record["raw"]["orientation"]
            },
        }
    return out
