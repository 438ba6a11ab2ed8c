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
from imucal.columns import SENSORS, SI_UNITS
from imucal.modelterms import ModelTerms
from imucal.modelterms.contract import Samples
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


#: The method of a sensor a partial session's calibration does not calibrate (its ``missing``):
#: read as the identity, so that applying the calibration passes its readings through, said.
NOT_CALIBRATED = "not calibrated"


def _not_calibrated(sensor: str, reason: str) -> SensorCalibration:
    return SensorCalibration(
        sensor, np.zeros(3), np.eye(3), SI_UNITS[sensor], method=f"{NOT_CALIBRATED}: {reason}"
    )


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
            Term name -> what its check flags (:meth:`~imucal.modelterms.contract.ModelTerm.check`), for
            the terms that flag something; a temperature term: per sensor, how many samples are
            outside its calibrated span (within the margin), ``{'temperature': {sensor:
            {...}}}``. Empty without terms.

        Raises
        ------
        ValueError
            For readings in another unit, a temperature term without ``temp_c``, samples
            farther outside the calibrated temperature span than its margin, or a lever arm
            without ``t_s`` or without a gyroscope reading in the recording.
        """
        samples = Samples(readings, self._sensors(), temp_c, t_s, source)
        for s in SENSORS:
            cal = self.sensor(s)
            if units[s] != cal.unit:
                raise ValueError(
                    f"{source}: {s} calibration expects readings in {cal.unit!r}, got {units[s]!r}"
                )
        flags = {}
        for term in self.terms.values():
            flag = term.check(samples)
            if flag:
                flags[term.name] = flag
        values, _ = self._paper(samples)
        for term in self.terms.values():
            values = term.correct(values, samples)
        return values, flags

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
        samples = Samples(readings, self._sensors(), temp_c, t_s)
        values, brackets = self._paper(samples)
        out = {}
        for s in SENSORS:
            cal = self.sensor(s)
            if cal.covariance is not None:
                cov = calibrated_covariance(cal.matrix, np.zeros(3), cal.covariance, brackets[s])
                out[s] = np.clip(np.diagonal(cov, axis1=1, axis2=2), 0, None)
        for term in self.terms.values():
            for s, variance in term.variance(values, brackets, samples).items():
                out[s] = out.get(s, 0.0) + variance
            values = term.correct(values, samples)
        return out

    def _sensors(self) -> dict[str, SensorCalibration]:
        return {s: self.sensor(s) for s in SENSORS}

    def _paper(self, samples: Samples) -> tuple[dict, dict]:
        """The values by eq. 11 with the terms' corrections of the readings, and the brackets
        they are made of (sensor -> (n, 3) each)."""
        values, brackets = {}, {}
        for s in SENSORS:
            cal = self.sensor(s)
            bracket = np.asarray(samples.readings[s], dtype=float) - cal.bias
            for term in self.terms.values():
                bracket = term.correct_reading(s, bracket, samples)
            brackets[s] = bracket
            values[s] = bracket @ cal.matrix.T
        return values, brackets

    def with_terms(self, terms: ModelTerms) -> ImuCalibration:
        """The same bias and matrices with ``terms``."""
        return ImuCalibration(self.acc, self.gyr, self.mag, terms)

    @property
    def not_calibrated(self) -> dict:
        """Sensor -> why it is not calibrated (the ``missing`` of a partial session)."""
        prefix = f"{NOT_CALIBRATED}: "
        return {
            s: self.sensor(s).method[len(prefix) :]
            for s in SENSORS
            if self.sensor(s).method.startswith(prefix)
        }

    def to_dict(self) -> dict:
        out: dict = {"format_version": FORMAT_VERSION, "frame": FRAME, "convention": CONVENTION}
        missing = self.not_calibrated
        for s in SENSORS:
            if s not in missing:
                out[s] = self.sensor(s).to_dict()
        if missing:
            out["missing"] = missing
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
        # a partial session's calibration names the sensors it could not calibrate, and why
        stated = dict(d.get("missing") or {})
        missing = [s for s in SENSORS if s not in d and s not in stated]
        if missing:
            raise ValueError(
                f"calibration lacks the sensors {missing} (neither calibrated nor listed in "
                "'missing')"
            )
        terms = ModelTerms.from_dict(d["terms"]) if version >= 2 and "terms" in d else ModelTerms()
        return cls(
            *(
                SensorCalibration.from_dict(s, d[s]) if s in d else _not_calibrated(s, stated[s])
                for s in SENSORS
            ),
            terms,
        )
