"""Calibration parameters of the three sensors, as frozen dataclasses with a versioned dict form.

``calibrated = matrix @ (reading - bias)`` with ``reading = counts * sensitivity`` in SI units
(the magnetometer normalised), plus the optional model terms of :mod:`imucal.modelterms`
(temperature polynomials, g-sensitivity, magnetometer delay). Files are written and read by
:mod:`imucal.io`. Format 2 adds the key ``terms`` (present only when a term is in the model);
format 1 files are read as calibrations without terms.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from imucal import errormodel
from imucal.columns import SENSORS, SI_UNITS, TEMPERATURE_COLUMNS
from imucal.modelterms import ModelTerms
from imucal.uncertainty import PARAMETERS, calibrated_covariance

#: Version of the calibration file format written by this package (2: optional ``terms``).
FORMAT_VERSION = 2

CONVENTION = "calibrated = matrix @ (reading - bias); reading = counts * sensitivity"
FRAME = "B: the rotation axes of the 3-D platform (phase x rotates about x of B, ...)"

_STD_KEYS = ("bias", "matrix", "scale", "xi_rad", "alpha_rad")


def _vector(values: Any, name: str) -> np.ndarray:
    v = np.asarray(values, dtype=float)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ValueError(f"{name} must be 3 finite numbers, got {values!r}")
    return v


def _matrix(values: Any, name: str) -> np.ndarray:
    m = np.asarray(values, dtype=float)
    if m.shape != (3, 3) or not np.all(np.isfinite(m)):
        raise ValueError(f"{name} must be a finite 3x3 matrix, got {values!r}")
    return m


@dataclass(frozen=True)
class SensorCalibration:
    """Calibration of one tri-axial sensor.

    Attributes
    ----------
    sensor : str
        'acc', 'gyr' or 'mag'.
    bias : ndarray, shape (3,)
        Bias ``o`` in ``unit`` (eq. 1).
    matrix : ndarray, shape (3, 3)
        ``T_R T_N S`` (eq. 11), maps a bias-free reading to frame B.
    unit : str
        Unit of the readings it accepts and of its output ('m/s^2', 'rad/s', 'normalised').
    std : dict
        Standard deviations where known, keys among 'bias' (3), 'matrix' (3x3), 'scale' (3),
        'xi_rad' (3), 'alpha_rad' (3).
    method : str
        Which method variant produced it (free text for the report).
    covariance : ndarray, shape (21, 21), or None
        Covariance of :data:`imucal.uncertainty.PARAMETERS` (bias, matrix row by row, scale,
        xi, alpha), None where unknown. Optional in the file: older files have none.
    quality : dict
        Goodness of fit of the stages behind it: stage -> ``GoodnessOfFit.to_dict()`` (or the
        stage's own statement of how its covariance was scaled). Optional in the file.
    """

    sensor: str
    bias: np.ndarray
    matrix: np.ndarray
    unit: str
    std: dict = field(default_factory=dict)
    method: str = ""
    covariance: np.ndarray | None = None
    quality: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.sensor not in SENSORS:
            raise ValueError(f"unknown sensor {self.sensor!r}; expected one of {SENSORS}")
        object.__setattr__(self, "bias", _vector(self.bias, f"{self.sensor}.bias"))
        object.__setattr__(self, "matrix", _matrix(self.matrix, f"{self.sensor}.matrix"))
        unknown = set(self.std) - set(_STD_KEYS)
        if unknown:
            raise ValueError(f"{self.sensor}.std has unknown keys {sorted(unknown)}")
        if self.covariance is not None:
            c = np.asarray(self.covariance, dtype=float)
            n = len(PARAMETERS)
            if c.shape != (n, n) or not np.all(np.isfinite(c)):
                raise ValueError(
                    f"{self.sensor}.covariance must be a finite ({n}, {n}) matrix over "
                    f"{PARAMETERS}, got shape {c.shape}"
                )
            object.__setattr__(self, "covariance", c)

    @property
    def decomposition(self) -> errormodel.Decomposition:
        """Scale, non-orthogonality and rotation of :attr:`matrix`."""
        return errormodel.decompose(self.matrix)

    def apply(self, readings: np.ndarray, unit: str) -> np.ndarray:
        """Calibrate ``readings`` (shape (n, 3), in ``unit``) to frame B.

        Raises
        ------
        ValueError
            If ``unit`` is not the unit this calibration was made for.
        """
        if unit != self.unit:
            raise ValueError(
                f"{self.sensor} calibration expects readings in {self.unit!r}, got {unit!r}"
            )
        return errormodel.apply(self.matrix, self.bias, readings)

    def to_dict(self) -> dict:
        d = self.decomposition
        return {
            "bias": self.bias.tolist(),
            "matrix": self.matrix.tolist(),
            "scale": d.scale.tolist(),
            "xi_rad": d.xi_rad.tolist(),
            "alpha_rad": d.alpha_rad.tolist(),
            "unit_in": self.unit,
            "unit_out": self.unit,
            "std": {k: np.asarray(v).tolist() for k, v in self.std.items()},
            "method": self.method,
            **(
                {"covariance": {"parameters": list(PARAMETERS), "matrix": self.covariance.tolist()}}
                if self.covariance is not None
                else {}
            ),
            **({"quality": self.quality} if self.quality else {}),
        }

    @classmethod
    def from_dict(cls, sensor: str, d: dict) -> "SensorCalibration":
        for key in ("bias", "matrix", "unit_in"):
            if key not in d:
                raise ValueError(f"calibration of {sensor!r} lacks the key {key!r}")
        if d["unit_in"] != SI_UNITS[sensor]:
            raise ValueError(
                f"calibration of {sensor!r} is for unit {d['unit_in']!r}, "
                f"this package works in {SI_UNITS[sensor]!r}"
            )
        std = {k: np.asarray(v, dtype=float) for k, v in d.get("std", {}).items()}
        covariance = None
        if d.get("covariance") is not None:
            names = tuple(d["covariance"].get("parameters", ()))
            if names != PARAMETERS:
                raise ValueError(
                    f"covariance of {sensor!r} is over the parameters {list(names)}; "
                    f"expected {list(PARAMETERS)}"
                )
            covariance = np.asarray(d["covariance"]["matrix"], dtype=float)
        return cls(
            sensor,
            d["bias"],
            d["matrix"],
            d["unit_in"],
            std,
            d.get("method", ""),
            covariance,
            dict(d.get("quality", {})),
        )


def _rate_per_sample(
    t_s: np.ndarray | None, omega: np.ndarray, source: str
) -> tuple[np.ndarray, np.ndarray]:
    """Times and the calibrated rate at every sample for the lever arm (rows without a gyro
    reading interpolated in time from their neighbours)."""
    if t_s is None:
        raise ValueError(
            f"{source}: the calibration has a lever arm; its tangential term needs the sample "
            "times (t_s), none were given"
        )
    t = np.asarray(t_s, dtype=float)
    ok = np.all(np.isfinite(omega), axis=1)
    if t.shape != (len(omega),) or not np.all(np.isfinite(t)) or np.any(np.diff(t) < 0):
        raise ValueError(
            f"{source}: the lever arm needs a finite, increasing time per sample "
            f"({len(omega)}), got shape {t.shape}"
        )
    if ok.sum() < 2:
        raise ValueError(
            f"{source}: the calibration has a lever arm, which needs the gyroscope's rate in "
            f"the same recording; {int(ok.sum())} of {len(omega)} samples have a gyro reading"
        )
    if ok.all():
        return t, omega
    return t, np.column_stack([np.interp(t, t[ok], omega[ok, j]) for j in range(3)])


@dataclass(frozen=True)
class ImuCalibration:
    """Calibration of accelerometer, gyroscope and magnetometer, all in frame B.

    Attributes
    ----------
    acc, gyr, mag : SensorCalibration
        The paper's bias and matrix of each sensor (at the temperature terms' ``reference_c``
        when the model has them).
    terms : ModelTerms
        Optional model terms (none by default).
    """

    acc: SensorCalibration
    gyr: SensorCalibration
    mag: SensorCalibration
    terms: ModelTerms = field(default_factory=ModelTerms)

    def sensor(self, name: str) -> SensorCalibration:
        if name not in SENSORS:
            raise ValueError(f"unknown sensor {name!r}; expected one of {SENSORS}")
        return getattr(self, name)

    def calibrate(
        self,
        readings: Mapping[str, np.ndarray],
        units: Mapping[str, str],
        *,
        temp_c: np.ndarray | None = None,
        t_s: np.ndarray | None = None,
        source: str = "the recording",
    ) -> tuple[dict, dict]:
        """Calibrate the readings of the three sensors with the whole model.

        The paper's ``matrix @ (reading - bias)`` (eq. 11) with every term the model has, in the
        order of :mod:`imucal.modelterms`.

        Parameters
        ----------
        readings : dict of str to ndarray, shape (n, 3)
            Sensor -> readings in SI units (sensor frame); rows of one sample.
        units : dict of str to str
            Sensor -> unit of its readings (must be the calibration's).
        temp_c : ndarray, shape (n,), optional
            Temperature of each sample (deg C, finite); required when the model has a
            temperature term.
        t_s : ndarray, shape (n,), optional
            Time of each sample (s, increasing); required when the model has a lever arm (its
            tangential term differentiates the gyroscope's rate).
        source : str
            What the readings come from (a file name), named in errors.

        Returns
        -------
        calibrated : dict of str to ndarray, shape (n, 3)
            Frame B, SI.
        flags : dict
            Per sensor with a temperature term, how many samples are outside its calibrated span
            (within the margin): ``{'temperature': {sensor: {...}}}``; empty without terms.

        Raises
        ------
        ValueError
            For readings in another unit, a temperature term without ``temp_c``, samples
            farther outside the calibrated temperature span than its margin, or a lever arm
            without ``t_s`` or without a gyroscope reading in the recording.
        """
        terms = self.terms
        flags: dict = {}
        out = {}
        for s in SENSORS:
            cal = self.sensor(s)
            if units[s] != cal.unit:
                raise ValueError(
                    f"{source}: {s} calibration expects readings in {cal.unit!r}, got {units[s]!r}"
                )
            values = np.asarray(readings[s], dtype=float)
            poly = terms.temperature.get(s)
            if poly is None:
                out[s] = errormodel.apply(cal.matrix, cal.bias, values)
                continue
            if temp_c is None:
                raise ValueError(
                    f"{source}: the calibration has a temperature term for {s}; the recording "
                    f"has no temperature column (expected one of {list(TEMPERATURE_COLUMNS)})"
                )
            temp = np.asarray(temp_c, dtype=float)
            if temp.shape != (len(values),) or not np.all(np.isfinite(temp)):
                raise ValueError(
                    f"{source}: the temperature must be a finite value per sample "
                    f"({len(values)}), got shape {temp.shape}"
                )
            flags.setdefault("temperature", {})[s] = poly.check_span(temp, source)
            out[s] = errormodel.apply(cal.matrix, np.zeros(3), poly.correct(values, cal.bias, temp))
        if terms.g_sensitivity is not None:
            out["gyr"] = out["gyr"] - out["acc"] @ terms.g_sensitivity.matrix.T
        if terms.lever_arm is not None:
            out["acc"] = out["acc"] - terms.lever_arm.acceleration(
                *_rate_per_sample(t_s, out["gyr"], source)
            )
        if terms.mag_delay is not None:
            out["mag"] = out["mag"] - terms.mag_delay.correction(out["gyr"], out["mag"])
        return out, flags

    def parameter_variance(
        self,
        readings: Mapping[str, np.ndarray],
        *,
        temp_c: np.ndarray | None = None,
        t_s: np.ndarray | None = None,
    ) -> dict:
        """Variance of every calibrated value from the uncertainty of the calibration's
        parameters, first order: the bias and matrix through their covariance
        (:func:`imucal.uncertainty.calibrated_covariance`, its diagonal) plus each term's
        coefficients through their standard deviations (taken as independent of each other
        and of the bias and matrix; :mod:`imucal.modelterms`). Left out: the reading's own
        noise, and one sensor's parameters reaching another through a term (the gyroscope's
        through the lever arm's and the magnetometer delay's rate, the accelerometer's through
        the g-sensitivity): second order in the small terms.

        Parameters
        ----------
        readings : dict of str to ndarray, shape (n, 3)
            As for :meth:`calibrate` (units already checked by it).
        temp_c, t_s : ndarray, shape (n,), optional
            As for :meth:`calibrate` (needed by the same terms).

        Returns
        -------
        dict of str to ndarray, shape (n, 3)
            Sensor -> variance (SI^2), for the sensors with a covariance or a term; others
            are left out.
        """
        terms = self.terms
        out, paper = {}, {}
        for s in SENSORS:
            cal = self.sensor(s)
            values = np.asarray(readings[s], dtype=float)
            poly = terms.temperature.get(s)
            corrected = (
                values - cal.bias if poly is None else poly.correct(values, cal.bias, temp_c)
            )
            paper[s] = corrected @ cal.matrix.T
            if cal.covariance is not None:
                cov = calibrated_covariance(cal.matrix, np.zeros(3), cal.covariance, corrected)
                out[s] = np.clip(np.diagonal(cov, axis1=1, axis2=2), 0, None)
            if poly is not None:
                out[s] = out.get(s, 0.0) + poly.variance(cal.matrix, corrected, temp_c)
        omega = paper["gyr"]
        if terms.g_sensitivity is not None:
            out["gyr"] = out.get("gyr", 0.0) + terms.g_sensitivity.variance(paper["acc"])
            omega = omega - paper["acc"] @ terms.g_sensitivity.matrix.T
        if terms.lever_arm is not None:
            t, rate = _rate_per_sample(t_s, omega, "the recording")
            out["acc"] = out.get("acc", 0.0) + terms.lever_arm.variance(t, rate)
        if terms.mag_delay is not None:
            out["mag"] = out.get("mag", 0.0) + terms.mag_delay.variance(omega, paper["mag"])
        return out

    def with_terms(self, terms: ModelTerms) -> ImuCalibration:
        """The same bias and matrices with ``terms``."""
        return ImuCalibration(self.acc, self.gyr, self.mag, terms)

    def to_dict(self) -> dict:
        out: dict = {"format_version": FORMAT_VERSION, "frame": FRAME, "convention": CONVENTION}
        for s in SENSORS:
            out[s] = self.sensor(s).to_dict()
        if not self.terms.empty:
            out["terms"] = self.terms.to_dict()
        return out

    @classmethod
    def from_dict(cls, d: dict) -> "ImuCalibration":
        version = d.get("format_version")
        if not isinstance(version, int):
            raise ValueError(f"calibration lacks an integer 'format_version', got {version!r}")
        if version > FORMAT_VERSION:
            raise ValueError(
                f"calibration format_version {version} is newer than this package "
                f"supports ({FORMAT_VERSION}); upgrade the package"
            )
        missing = [s for s in SENSORS if s not in d]
        if missing:
            raise ValueError(f"calibration lacks the sensors {missing}")
        terms = ModelTerms.from_dict(d["terms"]) if version >= 2 and "terms" in d else ModelTerms()
        return cls(*(SensorCalibration.from_dict(s, d[s]) for s in SENSORS), terms)
