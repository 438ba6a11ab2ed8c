"""Validation against a factory-calibrated reference IMU (Xsens MTx), as in Fig. 20 of the paper.

The reference rides on the platform with the module but has its own clock and its own axes.
Three steps bring it into the module's frame B and time base:

1. **Time alignment.** The squared rate magnitude ``|omega|^2`` does not depend on the mounting,
   so the module's and the reference's are cross-correlated (coarse lag on a common grid), then
   refined by non-linear least squares with sub-sample resolution and a linear clock drift.
   The square, not ``|omega|``: noise raises the mean of ``|omega|^2`` by a constant (``3
   sigma^2``) that the fitted offset absorbs, while it bends ``|omega|`` near rest, which
   shifts starts and stops of rotations in opposite directions by milliseconds.
   Convention::

       t_ref = offset_s + (1 + drift_ppm * 1e-6) * t_module

   (``offset_s`` is the offset at ``t_module = 0``; ``offset_mid_s`` the offset at the centre of
   the overlap, where it is best determined).
2. **Mounting.** The rotation ``R`` with ``v_B = R @ v_ref`` from the time-aligned gyroscope and
   accelerometer vectors (weighted Wahba problem, solved with an SVD).
3. **Metrics** of the module before and after calibration against the aligned reference: the
   RMS of ``|module| - |reference|`` (Fig. 20), the RMS per axis, the angle between the vectors,
   and the reference-free dip-angle consistency in static poses.

Module samples are placed on the time axis by their packet counter (lost packets leave gaps,
rows are not assumed equally spaced). The magnetometer of the module (10 Hz) is compared only at
its own sample times; its missing rows are never filled.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from imucal.columns import ACC, GYR, MAG, SENSOR_COLUMNS, SENSORS, SEQ, TIME
from imucal.io.store import to_jsonable
from imucal.validation.mounting import estimate_mounting
from imucal.validation.timing import (
    align_reference,
    estimate_time_alignment,
    packet_times,
)

NO_REFERENCE_NOTE = (
    "no reference recording: only the reference-free checks (dip-angle consistency) are reported"
)


# --------------------------------------------------------------------------- metrics


def angles_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle between row vectors of ``a`` and ``b`` (shape (n, 3) each), degrees, shape (n,)."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    # atan2 of |a x b| and a.b is accurate for small angles, unlike arccos
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.sum(a * b, axis=1)))


def compare_vectors(module: np.ndarray, reference: np.ndarray, min_norm: float = 0.0) -> dict:
    """Agreement of module vectors with reference vectors in the same frame and at the same times.

    Parameters
    ----------
    module, reference : array_like, shape (n, 3)
        Rows with a NaN in either are skipped (e.g. the module magnetometer between its samples).
    min_norm : float
        The angle is averaged only over rows with ``|reference| > min_norm`` (a rate near zero
        has no direction), in the unit of the vectors.

    Returns
    -------
    dict
        ``n``; ``rms_norm_diff`` (RMS of ``|module| - |reference|``, Fig. 20), ``mean_norm_diff``;
        ``rms_axis`` (3, RMS per axis of the difference); ``rms_diff`` (RMS of ``|module -
        reference|``); ``n_angle``, ``mean_angle_deg``, ``rms_angle_deg``. Units of the vectors;
        NaN where no row qualifies.
    """
    m = np.asarray(module, dtype=float)
    r = np.asarray(reference, dtype=float)
    if m.shape != r.shape or m.ndim != 2 or m.shape[1] != 3:
        raise ValueError(f"expected two (n, 3) arrays of equal shape, got {m.shape}, {r.shape}")
    ok = np.all(np.isfinite(m), axis=1) & np.all(np.isfinite(r), axis=1)
    m, r = m[ok], r[ok]
    norm_diff = np.linalg.norm(m, axis=1) - np.linalg.norm(r, axis=1)
    diff = m - r
    directed = np.linalg.norm(r, axis=1) > min_norm
    ang = angles_deg(m[directed], r[directed])

    def rms(x: np.ndarray, axis: int | None = None) -> np.ndarray | float:
        return np.sqrt(np.mean(x**2, axis=axis)) if x.size else np.nan

    return {
        "n": int(ok.sum()),
        "rms_norm_diff": float(rms(norm_diff)),
        "mean_norm_diff": float(np.mean(norm_diff)) if norm_diff.size else np.nan,
        "rms_axis": np.asarray(rms(diff, axis=0) if diff.size else [np.nan] * 3).tolist(),
        "rms_diff": float(rms(np.linalg.norm(diff, axis=1))),
        "n_angle": int(directed.sum()),
        "mean_angle_deg": float(np.mean(ang)) if ang.size else np.nan,
        "rms_angle_deg": float(rms(ang)),
    }


def summarise_dip(acc: np.ndarray, mag: np.ndarray, mask: np.ndarray) -> dict:
    """Angle between specific force and magnetic field over the masked rows.

    In static poses gravity and the Earth's field keep a fixed angle (90 deg minus the dip
    angle) whatever the orientation, so its scatter measures the relative calibration of the
    accelerometer and the magnetometer without any reference.

    Parameters
    ----------
    acc : array_like, shape (n, 3)
        Specific force, m/s^2.
    mag : array_like, shape (n, 3)
        Magnetic field; NaN rows (no fresh sample) are skipped.
    mask : array_like of bool, shape (n,)
        Rows to use (static samples).

    Returns
    -------
    dict
        ``n``, ``mean_deg``, ``std_deg`` (NaN when fewer than 2 rows qualify).
    """
    acc = np.asarray(acc, dtype=float)
    mag = np.asarray(mag, dtype=float)
    mask = np.asarray(mask, dtype=bool)
    if acc.shape != mag.shape or mask.shape != acc.shape[:1]:
        raise ValueError(
            f"expected acc (n, 3), mag (n, 3) and mask (n,), got {acc.shape}, {mag.shape}, "
            f"{mask.shape}"
        )
    ok = mask & np.all(np.isfinite(acc), axis=1) & np.all(np.isfinite(mag), axis=1)
    ang = angles_deg(acc[ok], mag[ok])
    return {
        "n": int(ok.sum()),
        "mean_deg": float(np.mean(ang)) if ang.size >= 2 else np.nan,
        "std_deg": float(np.std(ang, ddof=1)) if ang.size >= 2 else np.nan,
    }


# --------------------------------------------------------------------------- entry point


def _vectors(table: pd.DataFrame, sensor: str) -> np.ndarray:
    return table[list(SENSOR_COLUMNS[sensor])].to_numpy(dtype=float)


def _check_table(table: pd.DataFrame, name: str) -> None:
    missing = [c for c in (TIME, SEQ, *ACC, *GYR, *MAG) if c not in table.columns]
    if missing:
        raise ValueError(f"{name} lacks the columns {missing}")


def validate(
    module: pd.DataFrame,
    module_raw: pd.DataFrame,
    reference: pd.DataFrame | None,
    static_mask: np.ndarray,
    min_rate_rad_s: float = 0.2,
    n_windows: int = 6,
) -> dict:
    """Validate a calibration on the rotation3d recording against the reference IMU.

    Parameters
    ----------
    module : DataFrame
        The module's rotation3d recording, calibrated (frame B, SI units): ``t_s``, ``seq``,
        ``acc_*`` (m/s^2), ``gyr_*`` (rad/s), ``mag_*`` (normalised, NaN between samples).
    module_raw : DataFrame
        The same rows before calibration (readings = counts * sensitivity).
    reference : DataFrame or None
        The ingested reference (its own axes and clock, SI units), or None.
    static_mask : array_like of bool, shape (n,)
        Static rows of the module recording (for the dip-angle check).
    min_rate_rad_s : float
        Gyroscope angles are averaged only where the reference rate exceeds this, rad/s.
    n_windows : int
        Windows for the offset scatter, see :func:`estimate_time_alignment`.

    Returns
    -------
    dict
        JSON-ready (NaN as None): ``reference`` (None, or the number of reference samples),
        ``note``, ``dip`` (``raw``, ``calibrated`` and, with a reference, ``reference``:
        see :func:`summarise_dip`), ``time_alignment`` (:meth:`TimeAlignment.to_dict`),
        ``mounting`` (:meth:`Mounting.to_dict`), ``metrics`` (``raw`` and ``calibrated``, per
        sensor :func:`compare_vectors` in frame B with the reference time-aligned and rotated).
        The last three are None without a reference.

    Raises
    ------
    ValueError
        If a table lacks a column, the two module tables differ in ``t_s``/``seq``, or the
        mask has the wrong length.
    """
    _check_table(module, "module")
    _check_table(module_raw, "module_raw")
    if len(module) != len(module_raw) or not (
        np.array_equal(module[SEQ].to_numpy(), module_raw[SEQ].to_numpy())
        and np.allclose(module[TIME].to_numpy(), module_raw[TIME].to_numpy())
    ):
        raise ValueError(
            f"module ({len(module)} rows) and module_raw ({len(module_raw)} rows) must hold the "
            "same rows (equal t_s and seq)"
        )
    mask = np.asarray(static_mask, dtype=bool)
    if mask.shape != (len(module),):
        raise ValueError(f"static_mask has shape {mask.shape}; expected ({len(module)},)")

    dip = {
        "raw": summarise_dip(_vectors(module_raw, "acc"), _vectors(module_raw, "mag"), mask),
        "calibrated": summarise_dip(_vectors(module, "acc"), _vectors(module, "mag"), mask),
    }
    result: dict = {
        "reference": None,
        "note": NO_REFERENCE_NOTE,
        "dip": dip,
        "time_alignment": None,
        "mounting": None,
        "metrics": None,
    }
    if reference is None:
        return to_jsonable(result)

    _check_table(reference, "reference")
    t_mod = packet_times(module[TIME].to_numpy(), module[SEQ].to_numpy())
    t_ref = packet_times(reference[TIME].to_numpy(), reference[SEQ].to_numpy())
    alignment = estimate_time_alignment(
        t_mod, _vectors(module, "gyr"), t_ref, _vectors(reference, "gyr"), n_windows
    )
    ref_axes = align_reference(reference, t_mod, alignment)
    mounting = estimate_mounting(
        {s: _vectors(module, s) for s in ("acc", "gyr")},
        {s: _vectors(ref_axes, s) for s in ("acc", "gyr")},
    )
    ref_b = align_reference(reference, t_mod, alignment, mounting.matrix)
    min_norm = {"acc": 0.0, "gyr": min_rate_rad_s, "mag": 0.0}
    metrics = {
        name: {
            s: compare_vectors(_vectors(table, s), _vectors(ref_b, s), min_norm[s]) for s in SENSORS
        }
        for name, table in (("raw", module_raw), ("calibrated", module))
    }
    # the reference at the same static rows where the module has a magnetometer sample
    module_mag_rows = np.all(np.isfinite(_vectors(module, "mag")), axis=1)
    dip["reference"] = summarise_dip(
        _vectors(ref_b, "acc"), _vectors(ref_b, "mag"), mask & module_mag_rows
    )
    result.update(
        reference=len(reference),
        note="module and reference compared in frame B after time alignment and mounting",
        time_alignment=alignment.to_dict(),
        mounting=mounting.to_dict(),
        metrics=metrics,
    )
    return to_jsonable(result)
