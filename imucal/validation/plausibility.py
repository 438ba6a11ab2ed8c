"""Is a fitted calibration worth shipping? Physical bounds and the comparison with its fallback.

Two checks stand between a fit and the calibration a session ships:

* **Physical plausibility** (:func:`check_bounds`): the scale factors and non-orthogonality
  angles of a consumer MEMS sensor lie within ranges its datasheet states
  (:data:`BOUNDS`, sources in ``docs/plausibility.md``). A fitted value outside its bound by
  more than :data:`CONFIDENT_SIGMA` of its own standard deviations is *implausible* (the
  calibration is refused); one outside but within that many standard deviations, or one whose
  interval is wider than the whole plausible range, is *undetermined* (shipped with a warning).
* **The fallback** (:func:`compare_with_fallback`): the simpler calibration the session would
  ship without the fit (bias only with the nominal matrix, or the nominal matrix itself) is
  compared with the fitted one on the same data, its own and held-out; a fit that does worse
  than its fallback is not shipped.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from imucal import errormodel

#: Windows over which a fitted gyroscope and its fallback are integrated and compared, s: the
#: middle one of the validation's default windows (``reference.windows_s``), long enough that
#: a wrong scale shows against the reference's noise.
FALLBACK_WINDOWS_S = (10.0,)
#: A value farther than this many of its standard deviations outside its bound is implausible.
CONFIDENT_SIGMA = 3.0
#: Below this sphere coverage an ellipsoid's axes trade off against each other (an ellipsoid
#: at 20 % gave relative scales 1.26 / 0.74 with small formal std): an implausible one is not
#: supported by its data, and is refused rather than warned about.
WEAK_COVERAGE_PCT = 50.0


@dataclass(frozen=True)
class Bounds:
    """Plausible ranges of one sensor's calibration matrix.

    Attributes
    ----------
    scale : (float, float)
        Range of each scale factor (diagonal of ``S``). For the magnetometer, whose output unit
        is the normalised field, the range of each scale relative to the geometric mean of the
        three (the field's magnitude is not a property of the sensor).
    nonorthogonality_deg : float
        Largest non-orthogonality angle (``T_N``, eq. 6), deg.
    relative : bool
        Whether ``scale`` is relative to the geometric mean of the three scales.
    source : str
        Where the bound comes from (docs/plausibility.md gives the details).
    """

    scale: tuple[float, float]
    nonorthogonality_deg: float
    relative: bool
    source: str


#: Per sensor, the bounds; see docs/plausibility.md for the datasheet values behind them.
BOUNDS: dict[str, Bounds] = {
    "gyr": Bounds(
        (0.8, 1.25),
        3.0,
        False,
        "consumer MEMS gyroscopes: sensitivity tolerance +-3 %, cross-axis sensitivity +-2 % "
        "(InvenSense MPU-6050/MPU-9250, Bosch BMI160 datasheets), but the module of Zhang et "
        "al. (2014, Table II) reads 13-15 % below its nominal sensitivity: scale bounds wide "
        "enough for it, non-orthogonality at about three times the cross-axis tolerance",
    ),
    "acc": Bounds(
        (0.9, 1.1),
        3.0,
        False,
        "consumer MEMS accelerometers: initial sensitivity tolerance +-3 %, cross-axis "
        "sensitivity +-2 % (InvenSense MPU-6050/MPU-9250, Bosch BMI160 datasheets); bounds at "
        "about three times the tolerance",
    ),
    "mag": Bounds(
        (0.85, 1.18),
        5.0,
        True,
        "magnetometers: axis sensitivity mismatch of a few % (AKM AK8963, PNI RM3100, "
        "Bosch BMM150 datasheets) plus the soft-iron distortion of a small board; +-15 % "
        "between axes and 5 deg of shear are beyond both",
    ),
}


def _parameters(matrix: np.ndarray, std_matrix: np.ndarray | None, relative: bool) -> list:
    """(name, value, std, kind) of the scales and non-orthogonality angles (deg) of a matrix."""
    parts = errormodel.decompose(np.asarray(matrix, dtype=float))
    scale = np.asarray(parts.scale, dtype=float)
    std = np.zeros((3, 3)) if std_matrix is None else np.nan_to_num(np.asarray(std_matrix, float))
    std_scale = np.abs(np.diag(std))
    if relative:
        mean = float(np.exp(np.mean(np.log(scale))))
        scale, std_scale = scale / mean, std_scale / mean
    # an off-diagonal entry of U over its scale is the angle's sine (small angles)
    std_xi = np.degrees(np.array([std[1, 2], std[0, 2], std[0, 1]]) / np.mean(parts.scale))
    label = "relative scale" if relative else "scale"
    out = [
        (f"{label} {a}", float(v), float(s), "scale") for a, v, s in zip("xyz", scale, std_scale)
    ]
    out += [
        (f"non-orthogonality xi_{a} (deg)", float(np.degrees(v)), float(s), "xi")
        for a, v, s in zip("xyz", parts.xi_rad, std_xi)
    ]
    return out


def check_bounds(
    sensor: str, matrix: np.ndarray, std_matrix: np.ndarray | None = None
) -> dict[str, list[str]]:
    """A calibration matrix against its sensor's physical bounds (:data:`BOUNDS`).

    Parameters
    ----------
    sensor : {'acc', 'gyr', 'mag'}
    matrix : array_like, shape (3, 3)
        The calibration matrix (``T_R T_N S`` or its upper-triangular part).
    std_matrix : array_like, shape (3, 3), optional
        Standard deviations of its entries (of the upper triangle); None: taken as exact.

    Returns
    -------
    dict
        ``implausible``: messages of values outside a bound by more than
        :data:`CONFIDENT_SIGMA` standard deviations; ``undetermined``: values outside but
        within that, or whose interval is wider than the plausible range.

    Raises
    ------
    ValueError
        For an unknown sensor.
    """
    if sensor not in BOUNDS:
        raise ValueError(f"no bounds for sensor {sensor!r}; expected one of {sorted(BOUNDS)}")
    bounds = BOUNDS[sensor]
    out: dict[str, list[str]] = {"implausible": [], "undetermined": []}
    low, high = bounds.scale
    limit = bounds.nonorthogonality_deg
    for name, value, std, kind in _parameters(matrix, std_matrix, bounds.relative):
        lo, hi = (low, high) if kind == "scale" else (-limit, limit)
        text = (
            f"{sensor} {name} = {value:.4g} (std {std:.2g}) against "
            f"the plausible range [{lo:g}, {hi:g}] ({bounds.source})"
        )
        outside = max(lo - value, value - hi, 0.0)
        if outside > CONFIDENT_SIGMA * std:
            out["implausible"].append(f"{text}: outside it")
        elif outside > 0:
            out["undetermined"].append(f"{text}: outside it, but within {CONFIDENT_SIGMA:g} std")
        elif 2 * CONFIDENT_SIGMA * std > hi - lo:
            out["undetermined"].append(f"{text}: its interval is wider than the range")
    return out


def _errors(found: Mapping[str, tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
    return np.concatenate([np.asarray(e, dtype=float) for _, e in found.values()] or [[]])


def compare_with_fallback(
    fitted: list[Mapping[str, tuple[np.ndarray, np.ndarray]]],
    fallback: list[Mapping[str, tuple[np.ndarray, np.ndarray]]],
) -> dict:
    """The fitted calibration's errors against its fallback's over the same windows.

    Parameters
    ----------
    fitted, fallback : list of mapping
        Per recording, the errors by window (``{key: (starts, errors)}`` as
        :func:`imucal.validation.orientation.window_errors` returns them), the same windows for
        both.

    Returns
    -------
    dict
        ``n``, ``median_deg`` and ``rms_deg`` of each (``fitted``, ``fallback``) and ``worse``:
        True when the fitted calibration's median or RMS error is larger than the fallback's
        (None without windows).
    """
    a = np.concatenate([_errors(f) for f in fitted] or [[]])
    b = np.concatenate([_errors(f) for f in fallback] or [[]])
    if a.size == 0 or b.size == 0:
        return {"n": 0, "worse": None}

    def stats(e: np.ndarray) -> dict:
        return {"median_deg": float(np.median(e)), "rms_deg": float(np.sqrt(np.mean(e**2)))}

    fit, fall = stats(a), stats(b)
    worse = fit["median_deg"] > fall["median_deg"] or fit["rms_deg"] > fall["rms_deg"]
    return {"n": int(a.size), "fitted": fit, "fallback": fall, "worse": bool(worse)}


def review_calibration(sensor: str, calibration: Mapping) -> dict[str, list[str]]:
    """:func:`check_bounds` of a calibration in its dict form (``SensorCalibration.to_dict``).

    Parameters
    ----------
    sensor : str
    calibration : mapping
        With ``matrix`` and optionally ``std.matrix``.

    Returns
    -------
    dict
        As :func:`check_bounds`; both lists empty for a sensor without bounds.
    """
    if sensor not in BOUNDS:
        return {"implausible": [], "undetermined": []}
    std = (calibration.get("std") or {}).get("matrix")
    return check_bounds(
        sensor,
        np.asarray(calibration["matrix"], dtype=float),
        None if std is None else np.asarray(std, dtype=float),
    )


def bound_warnings(stage: str, sensor: str, calibration: Mapping) -> list[str]:
    """Warnings of a calibration that is shipped whatever its bounds say (the full protocol's
    stages): each implausible or undetermined value, prefixed with the stage.

    Parameters
    ----------
    stage, sensor : str
    calibration : mapping
        As :func:`review_calibration` takes it.
    """
    found = review_calibration(sensor, calibration)
    return [f"{stage}: {w}; shipped with this warning" for w in found["undetermined"]] + [
        f"{stage}: {w}; implausible, but shipped (the full protocol has no simpler stage)"
        for w in found["implausible"]
    ]


def review_fit(sensor: str, calibration: Mapping, artifact: Mapping) -> dict[str, list[str]]:
    """Ship, warn or refuse a stage's calibration: its bounds, its support and its held-out data.

    * refused: the fit predicts data left out of it (``heldout_error_before_m_s2`` /
      ``heldout_error_after_m_s2``, e.g. the cube fit's left-out positions) worse than the
      nominal calibration; or a value is implausible (:func:`check_bounds`) and the data support
      the fit weakly (an ellipsoid below :data:`WEAK_COVERAGE_PCT` of the sphere);
    * warned: a value implausible on well-supported data (a right fit of a sensor whose declared
      sensitivity is off: the warning says to check it), or undetermined.

    Parameters
    ----------
    sensor : str
    calibration : mapping
        The stage's calibration (``SensorCalibration.to_dict``).
    artifact : mapping
        The stage's artifact (``coverage_pct``, held-out errors when it has them).

    Returns
    -------
    dict
        ``refuse`` and ``warn``: lists of messages.
    """
    bounds = review_calibration(sensor, calibration)
    refuse, warn = [], [f"{w}; shipped with this warning" for w in bounds["undetermined"]]
    if "heldout_error_after_m_s2" in artifact:
        before = np.asarray(artifact["heldout_error_before_m_s2"], dtype=float)
        after = np.asarray(artifact["heldout_error_after_m_s2"], dtype=float)
        rms_before, rms_after = np.sqrt(np.mean(before**2)), np.sqrt(np.mean(after**2))
        if rms_after > rms_before:
            refuse.append(
                f"on data left out of the fit it does worse than the nominal calibration (RMS "
                f"{rms_after:.3g} against {rms_before:.3g} over {after.size} left-out positions)"
            )
    coverage = artifact.get("coverage_pct")
    if coverage is not None and coverage < WEAK_COVERAGE_PCT:
        refuse += [
            f"{w}, on {coverage:.0f} % of the sphere (below {WEAK_COVERAGE_PCT:g} % the "
            "ellipsoid's axes trade off against each other)"
            for w in bounds["implausible"]
        ]
    else:
        warn += [
            f"{w}, although the data determine it: shipped with this warning; check the "
            "declared units and sensitivity (a nominal scale off by this much is more often "
            "a declaration than a sensor) and magnetic disturbances"
            for w in bounds["implausible"]
        ]
    return {"refuse": refuse, "warn": warn}
