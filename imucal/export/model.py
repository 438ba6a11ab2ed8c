"""What every export needs: the inertial calibration, the noise parameters, triangular factors.

Our model is ``calibrated = K (reading - b)`` per sensor (:mod:`imucal.calibration`), with a
full 3x3 ``K`` that maps to the platform frame B. The receiving tools split such a matrix into
a triangular scale-and-axis matrix and a rotation; :func:`lower_times_rotation` and
:func:`rotation_times_lower` are those splits (QR decompositions with the signs fixed so that
the triangular factor has a positive diagonal and the orthogonal one is a proper rotation).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from imucal.calibration import SensorCalibration
from imucal.modelterms import ModelTerms
from imucal.noise import sensor_noise

#: The IMU topic written when none is given (the one in Kalibr's and OpenVINS's examples).
ROSTOPIC = "/imu0"
#: Inflation of the Allan values that OpenVINS's calibration guide recommends for unmodelled
#: errors ("maybe 10-20x", docs/gs-calibration.dox); stated in the files, never applied.
RECOMMENDED_INFLATION = "10-20x (OpenVINS docs/gs-calibration.dox); not applied here"

_REVERSE = np.eye(3)[::-1]


def _check(matrix: np.ndarray, name: str) -> np.ndarray:
    m = np.asarray(matrix, dtype=float)
    if m.shape != (3, 3) or not np.all(np.isfinite(m)) or not np.linalg.det(m) > 0:
        raise ValueError(f"{name} must be a finite 3x3 matrix with a positive determinant")
    return m


def lower_times_rotation(matrix: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``matrix = L @ R``: L lower triangular with a positive diagonal, R a rotation.

    Raises
    ------
    ValueError
        If ``matrix`` is not 3x3, finite, with a positive determinant.
    """
    m = _check(matrix, "matrix")
    q, r = np.linalg.qr(m.T)  # m.T = q r, so m = r.T q.T
    lower, rot = r.T, q.T
    s = np.sign(np.diag(lower))
    return np.tril(lower * s) + 0.0, s[:, None] * rot  # + 0.0: no -0.0 above the diagonal


def rotation_times_lower(matrix: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``matrix = R @ L``: R a rotation, L lower triangular with a positive diagonal.

    Raises
    ------
    ValueError
        If ``matrix`` is not 3x3, finite, with a positive determinant.
    """
    m = _check(matrix, "matrix")
    q, r = np.linalg.qr(m @ _REVERSE)  # m P = q r, so m = (q P)(P r P), P r P lower
    rot, lower = q @ _REVERSE, _REVERSE @ r @ _REVERSE
    s = np.sign(np.diag(lower))
    return rot * s, np.tril(s[:, None] * lower) + 0.0


def inertial_calibration(calibration: Mapping) -> dict[str, SensorCalibration]:
    """Accelerometer and gyroscope calibration from a calibration.json content (full or partial).

    Raises
    ------
    ValueError
        If the accelerometer or the gyroscope is missing (a partial session that did not
        calibrate it) or malformed.
    """
    missing = [s for s in ("acc", "gyr") if s not in calibration]
    if missing:
        raise ValueError(
            f"the calibration lacks {missing}: the exports need the accelerometer and the "
            "gyroscope calibrated"
        )
    return {s: SensorCalibration.from_dict(s, calibration[s]) for s in ("acc", "gyr")}


def g_sensitivity(calibration: Mapping) -> np.ndarray:
    """The gyroscope's g-sensitivity ``G`` (rad/s per m/s^2, frame B; ``w_B = K (w_m - b) -
    G a_B``) of a calibration.json content, zeros when its model has none (3, 3)."""
    term = ModelTerms.from_dict(calibration.get("terms", {})).get("g_sensitivity")
    return np.zeros((3, 3)) if term is None else term.matrix


def terms_not_written(calibration: Mapping, fmt: str) -> list[str]:
    """Header lines naming the model terms of a calibration.json content that the export
    format ``fmt`` cannot carry (each term's :meth:`~imucal.modelterms.contract.ModelTerm.export_note`);
    empty when there are none."""
    terms = ModelTerms.from_dict(calibration.get("terms", {}))
    notes = [note for note in (term.export_note(fmt) for term in terms.values()) if note]
    if not notes:
        return []
    return [f"NOT in this file: the model terms {', '.join(notes)} of calibration.json (the tool",
            "has no place for them); calibrate with `imucal apply` to keep them (docs/exports.md)."]  # fmt: skip


@dataclass(frozen=True)
class NoiseParameters:
    """The per-sensor noise values the tools take (largest over the axes, SI).

    Attributes
    ----------
    acc_noise_density : float
        White noise N of the accelerometer, m/s^2/sqrt(Hz).
    acc_random_walk : float
        Rate random walk K of the accelerometer, m/s^3/sqrt(Hz).
    gyr_noise_density : float
        rad/s/sqrt(Hz).
    gyr_random_walk : float
        rad/s^2/sqrt(Hz).
    update_rate_hz : float
        Sample rate of the static recording, Hz.
    resolved : dict of str to bool
        Per value: True if every axis resolved the term; False if an upper bound stands in.
    """

    acc_noise_density: float
    acc_random_walk: float
    gyr_noise_density: float
    gyr_random_walk: float
    update_rate_hz: float
    resolved: dict

    def note(self, key: str) -> str:
        """How a value was obtained, for a comment next to it."""
        how = "Allan fit" if self.resolved[key] else "UPPER BOUND (term not resolved)"
        return f"{how}, largest axis"


def noise_parameters(noise: Mapping) -> NoiseParameters:
    """Noise densities and random walks of accelerometer and gyroscope from a noise.json.

    Raises
    ------
    ValueError
        If the noise stage did not analyse the accelerometer or the gyroscope.
    """
    values, resolved = {}, {}
    for sensor in ("acc", "gyr"):
        for term, key in (("N", "noise_density"), ("K", "random_walk")):
            value, ok = sensor_noise(noise, sensor, term)
            if value is None:
                raise ValueError(
                    f"noise.json has no {sensor} analysis "
                    f"(skipped: {noise.get('skipped', {}).get(sensor, 'no such columns')})"
                )
            values[f"{sensor}_{key}"], resolved[f"{sensor}_{key}"] = value, ok
    return NoiseParameters(
        **values, update_rate_hz=export_rate(noise["rate_hz"]), resolved=resolved
    )


#: Significant digits of the sample rate written in the exports.
RATE_DIGITS = 6


def export_rate(rate_hz: float) -> float:
    """The sample rate as the files give it, to :data:`RATE_DIGITS` significant digits, Hz.

    The rate comes from the median (or mean) time step, so a 100 Hz recording gives
    100.00000000000213 Hz; time stamps of 1 us resolution fix a 1 kHz rate to about 1e-3
    relative, so six digits keep all that is known.
    """
    return float(f"{float(rate_hz):.{RATE_DIGITS}g}")


def matrix_list(matrix: np.ndarray) -> list[list[float]]:
    """Rows of a matrix as plain floats (YAML)."""
    return [[float(v) for v in row] for row in np.asarray(matrix)]
