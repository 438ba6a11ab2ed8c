"""Optional terms of the calibration model beyond the paper's bias and matrix.

The paper's model is ``calibrated = K (reading - o)`` (eq. 11). A calibration may add terms the
gap diagnosis has shown a session needs (``docs/model-terms.md``); with all of them the
calibrated values of one sample are

1. temperature (per sensor, per axis): ``v = K (reading - o - b(dT)) / (1 + s(dT))``
   elementwise inside the bracket, with ``dT = T - reference_c`` and the polynomials
   ``b(dT) = sum_k bias[k-1] dT^k``, ``s(dT) = sum_k scale[k-1] dT^k`` (k = 1 .. order; the
   constant term is the paper's bias and matrix, which hold at ``reference_c``);
2. g-sensitivity of the gyroscope: ``w_B = v_gyr - G a_B`` with ``a_B`` the calibrated
   specific force of the same sample (``G`` in rad/s per m/s^2, frame B);
3. lever arm of the accelerometer from the rotation centre of the rate table:
   ``a_B = v_acc - w_B x (w_B x r) - dw_B/dt x r`` (``r`` in m, frame B; ``w_B`` the gyroscope's
   calibrated rate of the same sample, its derivative over :data:`LEVER_ARM_DIFF_S`);
4. magnetometer delay against acc/gyro: ``m_B = v_mag - delay (w_B x v_mag)``, the first-order
   advance of a field that turns in B at ``-w_B`` by the delay (s).

This module holds the terms as frozen dataclasses with their dict form (part of
``calibration.json``, format 2), their units and standard deviations, and the evaluation of
the temperature polynomials with the check of the calibrated temperature span. The
estimators are in :mod:`imucal.terms`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from imucal.columns import SENSORS, SI_UNITS

#: Names of the optional terms, in the order they are applied.
TERMS = ("temperature", "g_sensitivity", "lever_arm", "mag_delay")

#: Sensors a temperature polynomial may be estimated for.
TEMPERATURE_SENSORS = ("acc", "gyr")

#: Time (s) over which the lever arm's angular acceleration is taken (central difference of the
#: rate ``LEVER_ARM_DIFF_S`` apart): long enough that the gyroscope's white noise, divided by it,
#: adds less to the tangential term than the accelerometer's own noise (0.002 rad/s over 0.1 s
#: at r = 5 cm is 1e-3 m/s^2), short against a rate table's spin-up (about 1 s).
LEVER_ARM_DIFF_S = 0.1


def _coefficients(values: Any, name: str) -> np.ndarray:
    c = np.asarray(values, dtype=float).reshape(-1, 3)
    if not np.all(np.isfinite(c)):
        raise ValueError(f"{name} must be finite rows of 3 coefficients, got {values!r}")
    return c


@dataclass(frozen=True)
class TemperaturePolynomial:
    """Temperature dependence of one sensor's bias and scale, per axis of the reading.

    Attributes
    ----------
    sensor : str
        'acc' or 'gyr'.
    reference_c : float
        Temperature (deg C) at which the calibration's bias and matrix hold.
    span_c : tuple of float
        Lowest and highest temperature (deg C) of the samples the polynomials were fitted on.
    margin_c : float
        How far outside ``span_c`` (K) a sample may be and still be calibrated (flagged);
        beyond it the calibration is refused.
    bias : ndarray, shape (p, 3)
        Row ``k-1``: coefficient of ``dT^k`` of the bias drift of each axis, in the sensor's
        unit per K^k (m/s^2/K^k, rad/s/K^k). ``p`` is the bias order (0: none).
    scale : ndarray, shape (q, 3)
        Row ``k-1``: coefficient of ``dT^k`` of the relative scale change of each axis (1/K^k).
    bias_std, scale_std : ndarray, same shapes
        Standard deviations of the coefficients.
    method : str
        How they were estimated (free text for the report).
    bias_covariance : ndarray, shape (3, p, p), optional
        Covariance of each axis's bias coefficients (rows and columns in ``bias``'s row
        order); None when only the standard deviations are known.
    """

    sensor: str
    reference_c: float
    span_c: tuple
    margin_c: float
    bias: np.ndarray
    scale: np.ndarray
    bias_std: np.ndarray
    scale_std: np.ndarray
    method: str = ""
    bias_covariance: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.sensor not in TEMPERATURE_SENSORS:
            raise ValueError(
                f"temperature term of unknown sensor {self.sensor!r}; "
                f"expected one of {TEMPERATURE_SENSORS}"
            )
        lo, hi = (float(x) for x in self.span_c)
        if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
            raise ValueError(
                f"{self.sensor} temperature span_c must be [low, high], got {self.span_c!r}"
            )
        if not self.margin_c >= 0:
            raise ValueError(
                f"{self.sensor} temperature margin_c must be >= 0 K, got {self.margin_c}"
            )
        object.__setattr__(self, "span_c", (lo, hi))
        object.__setattr__(self, "reference_c", float(self.reference_c))
        object.__setattr__(self, "margin_c", float(self.margin_c))
        for name in ("bias", "scale", "bias_std", "scale_std"):
            object.__setattr__(
                self, name, _coefficients(getattr(self, name), f"{self.sensor}.{name}")
            )
        if self.bias_std.shape != self.bias.shape or self.scale_std.shape != self.scale.shape:
            raise ValueError(f"{self.sensor} temperature std must have the coefficients' shapes")
        if self.bias_covariance is not None:
            p = len(self.bias)
            cov = np.asarray(self.bias_covariance, dtype=float).reshape(3, p, p)
            if not np.all(np.isfinite(cov)):
                raise ValueError(f"{self.sensor} temperature bias_covariance must be finite")
            object.__setattr__(self, "bias_covariance", cov)

    @property
    def unit(self) -> str:
        return SI_UNITS[self.sensor]

    def check_span(self, temp_c: np.ndarray, source: str) -> dict:
        """Refuse temperatures beyond the span by more than the margin; say how many are outside.

        Parameters
        ----------
        temp_c : ndarray, shape (n,)
            Temperature of each sample (deg C), finite.
        source : str
            What the samples come from (file name), for the message.

        Returns
        -------
        dict
            ``outside_fraction`` (samples outside ``span_c`` but within the margin) and
            ``max_outside_k`` (how far the farthest one is, K).

        Raises
        ------
        ValueError
            If a sample is farther than ``margin_c`` outside ``span_c``.
        """
        lo, hi = self.span_c
        beyond = np.maximum(lo - temp_c, temp_c - hi)
        worst = float(np.max(beyond)) if len(beyond) else 0.0
        if worst > self.margin_c:
            raise ValueError(
                f"{source}: temperature {float(np.min(temp_c)):.2f}..{float(np.max(temp_c)):.2f} "
                f"deg C is outside the {self.sensor} calibration's span {lo:.2f}..{hi:.2f} deg C "
                f"by {worst:.2f} K, more than the margin {self.margin_c:g} K; the temperature "
                "polynomial is not extrapolated that far"
            )
        return {
            "outside_fraction": float(np.mean(beyond > 0)) if len(beyond) else 0.0,
            "max_outside_k": max(worst, 0.0),
        }

    def drift(self, temp_c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Bias drift and relative scale change at ``temp_c`` (shape (n,), deg C).

        Returns
        -------
        bias : ndarray, shape (n, 3)
            ``b(dT)`` in the sensor's unit.
        scale : ndarray, shape (n, 3)
            ``s(dT)``, dimensionless.
        """
        d_t = np.asarray(temp_c, dtype=float)[:, None] - self.reference_c
        bias = sum((c * d_t**k for k, c in enumerate(self.bias, 1)), np.zeros((len(d_t), 3)))
        scale = sum((c * d_t**k for k, c in enumerate(self.scale, 1)), np.zeros((len(d_t), 3)))
        return bias, scale

    def correct(self, values: np.ndarray, bias: np.ndarray, temp_c: np.ndarray) -> np.ndarray:
        """``(reading - bias - b(dT)) / (1 + s(dT))`` per axis (n, 3): the reading freed of
        the constant bias and the drift, at the scale of ``reference_c``."""
        drift, scale = self.drift(temp_c)
        return (values - bias - drift) / (1.0 + scale)

    def variance(self, matrix: np.ndarray, corrected: np.ndarray, temp_c: np.ndarray) -> np.ndarray:
        """Variance (n, 3) the coefficients' standard deviations give the calibrated values
        ``matrix @ corrected`` (first order, coefficients independent).

        ``v = K (r - o - b(dT)) / (1 + s(dT))``: a bias coefficient moves ``v`` by ``-K[:, j]
        dT^k / (1 + s_j)``, a scale coefficient by ``-K[:, j] corrected_j dT^k / (1 + s_j)``.
        An axis's bias coefficients with their covariance where it is known.

        Parameters
        ----------
        matrix : ndarray, shape (3, 3)
        corrected : ndarray, shape (n, 3)
            :meth:`correct` of the readings.
        temp_c : ndarray, shape (n,)
        """
        d_t = np.asarray(temp_c, dtype=float)[:, None] - self.reference_c
        _, scale = self.drift(temp_c)
        per_axis = np.zeros((len(d_t), 3))  # variance of the bracket's axis j
        if self.bias_covariance is not None and len(self.bias):
            powers = d_t[:, :, None] ** np.arange(1, len(self.bias) + 1)  # (n, 3, p)
            per_axis += np.einsum("njp,jpq,njq->nj", powers, self.bias_covariance, powers)
        else:
            for k, std in enumerate(self.bias_std, 1):
                per_axis += (std * d_t**k) ** 2
        for k, std in enumerate(self.scale_std, 1):
            per_axis += (std * corrected * d_t**k) ** 2
        return (per_axis / (1.0 + scale) ** 2) @ (np.asarray(matrix) ** 2).T

    def to_dict(self) -> dict:
        return {
            "reference_c": self.reference_c,
            "span_c": list(self.span_c),
            "margin_c": self.margin_c,
            "bias_order": len(self.bias),
            "bias": self.bias.tolist(),
            "bias_std": self.bias_std.tolist(),
            "bias_unit": f"{self.unit}/K^k (row k-1: coefficient of (T - reference_c)^k)",
            "scale_order": len(self.scale),
            "scale": self.scale.tolist(),
            "scale_std": self.scale_std.tolist(),
            "scale_unit": "1/K^k (row k-1: coefficient of (T - reference_c)^k)",
            "method": self.method,
            **(
                {"bias_covariance": self.bias_covariance.tolist()}
                if self.bias_covariance is not None
                else {}
            ),
        }

    @classmethod
    def from_dict(cls, sensor: str, d: dict) -> TemperaturePolynomial:
        for key in ("reference_c", "span_c", "margin_c", "bias", "scale"):
            if key not in d:
                raise ValueError(f"temperature term of {sensor!r} lacks the key {key!r}")
        return cls(
            sensor,
            d["reference_c"],
            tuple(d["span_c"]),
            d["margin_c"],
            d["bias"],
            d["scale"],
            d.get("bias_std", np.zeros_like(np.asarray(d["bias"], dtype=float))),
            d.get("scale_std", np.zeros_like(np.asarray(d["scale"], dtype=float))),
            d.get("method", ""),
            d.get("bias_covariance"),
        )


@dataclass(frozen=True)
class GSensitivity:
    """Gyroscope output per specific force, in frame B: ``w_B -= matrix @ a_B``.

    Attributes
    ----------
    matrix : ndarray, shape (3, 3)
        rad/s per m/s^2; row: gyro axis of B, column: specific-force axis of B.
    std : ndarray, shape (3, 3)
    method : str
    """

    matrix: np.ndarray
    std: np.ndarray
    method: str = ""

    def __post_init__(self) -> None:
        for name in ("matrix", "std"):
            m = np.asarray(getattr(self, name), dtype=float)
            if m.shape != (3, 3) or not np.all(np.isfinite(m)):
                raise ValueError(f"g_sensitivity.{name} must be a finite 3x3 matrix, got {m!r}")
            object.__setattr__(self, name, m)

    def variance(self, acc_b: np.ndarray) -> np.ndarray:
        """Variance (n, 3) of ``matrix @ a_B`` from the entries' standard deviations (first
        order, independent) for the specific force ``acc_b`` (n, 3, m/s^2)."""
        return np.asarray(acc_b) ** 2 @ (self.std**2).T

    def to_dict(self) -> dict:
        return {
            "matrix": self.matrix.tolist(),
            "std": self.std.tolist(),
            "unit": "rad/s per m/s^2 (frame B; row: gyro axis, column: specific-force axis)",
            "method": self.method,
        }

    @classmethod
    def from_dict(cls, d: dict) -> GSensitivity:
        if "matrix" not in d:
            raise ValueError("g_sensitivity term lacks the key 'matrix'")
        return cls(d["matrix"], d.get("std", np.zeros((3, 3))), d.get("method", ""))


def angular_acceleration(t_s: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """Derivative of the rate, central difference over :data:`LEVER_ARM_DIFF_S`.

    Parameters
    ----------
    t_s : ndarray, shape (n,)
        Sample times (s), increasing.
    omega : ndarray, shape (n, 3)
        Rate (rad/s), finite.

    Returns
    -------
    ndarray, shape (n, 3)
        rad/s^2; at the ends the difference is one-sided over what the recording has.
    """
    h = 0.5 * LEVER_ARM_DIFF_S
    lo = np.clip(t_s - h, t_s[0], t_s[-1])
    hi = np.clip(t_s + h, t_s[0], t_s[-1])
    span = np.where(hi > lo, hi - lo, np.inf)
    ahead = np.column_stack([np.interp(hi, t_s, omega[:, j]) for j in range(3)])
    behind = np.column_stack([np.interp(lo, t_s, omega[:, j]) for j in range(3)])
    return (ahead - behind) / span[:, None]


@dataclass(frozen=True)
class LeverArm:
    """Position of the accelerometer relative to the rate table's rotation centre, in B.

    The accelerometer senses ``w x (w x r) + dw/dt x r`` on top of the specific force at the
    centre; the term removes it with the gyroscope's rate of the same sample.

    Attributes
    ----------
    r_m : ndarray, shape (3,)
        Lever arm (m), frame B.
    std_m : ndarray, shape (3,)
        Standard deviations (m).
    method : str
    """

    r_m: np.ndarray
    std_m: np.ndarray
    method: str = ""

    def __post_init__(self) -> None:
        for name in ("r_m", "std_m"):
            v = np.asarray(getattr(self, name), dtype=float)
            if v.shape != (3,) or not np.all(np.isfinite(v)):
                raise ValueError(f"lever_arm.{name} must be 3 finite values (m), got {v!r}")
            object.__setattr__(self, name, v)

    @staticmethod
    def _sensed(omega: np.ndarray, w_dot: np.ndarray, r: np.ndarray) -> np.ndarray:
        """``w x (w x r) + dw/dt x r`` (n, 3): linear in ``r``."""
        return np.cross(omega, np.cross(omega, r)) + np.cross(w_dot, r)

    def acceleration(self, t_s: np.ndarray, omega: np.ndarray) -> np.ndarray:
        """``w x (w x r) + dw/dt x r`` (m/s^2, shape (n, 3)) for rates ``omega`` (rad/s, frame
        B, shape (n, 3), finite) at times ``t_s`` (s, shape (n,))."""
        return self._sensed(omega, angular_acceleration(t_s, omega), self.r_m)

    def variance(self, t_s: np.ndarray, omega: np.ndarray) -> np.ndarray:
        """Variance (n, 3) of :meth:`acceleration` from ``std_m`` (independent axes): it is
        linear in ``r``, its column j that of ``e_j``."""
        w_dot = angular_acceleration(t_s, omega)
        return sum((self._sensed(omega, w_dot, e) * sd) ** 2
                   for e, sd in zip(np.eye(3), self.std_m, strict=True))  # fmt: skip

    def to_dict(self) -> dict:
        return {
            "r_m": self.r_m.tolist(),
            "std_m": self.std_m.tolist(),
            "unit": "m (frame B; accelerometer relative to the rate table's rotation centre)",
            "method": self.method,
        }

    @classmethod
    def from_dict(cls, d: dict) -> LeverArm:
        if "r_m" not in d:
            raise ValueError("lever_arm term lacks the key 'r_m'")
        return cls(d["r_m"], d.get("std_m", np.zeros(3)), d.get("method", ""))


@dataclass(frozen=True)
class MagDelay:
    """Delay of the magnetometer behind acc/gyro (s): its reading is the field of
    ``delay_s`` earlier (mean age of a held sample included).

    Attributes
    ----------
    delay_s : float
    std_s : float
    method : str
    """

    delay_s: float
    std_s: float
    method: str = ""

    def __post_init__(self) -> None:
        for name in ("delay_s", "std_s"):
            v = float(getattr(self, name))
            if not np.isfinite(v):
                raise ValueError(f"mag_delay.{name} must be finite, got {v}")
            object.__setattr__(self, name, v)

    def correction(self, omega: np.ndarray, mag: np.ndarray) -> np.ndarray:
        """``delay (w_B x m_B)`` (n, 3), what the term takes from the calibrated field."""
        return self.delay_s * np.cross(omega, mag)

    def variance(self, omega: np.ndarray, mag: np.ndarray) -> np.ndarray:
        """Variance (n, 3) of :meth:`correction` from ``std_s``."""
        return (self.std_s * np.cross(omega, mag)) ** 2

    def to_dict(self) -> dict:
        return {"delay_s": self.delay_s, "std_s": self.std_s, "unit": "s", "method": self.method}

    @classmethod
    def from_dict(cls, d: dict) -> MagDelay:
        if "delay_s" not in d:
            raise ValueError("mag_delay term lacks the key 'delay_s'")
        return cls(d["delay_s"], d.get("std_s", 0.0), d.get("method", ""))


@dataclass(frozen=True)
class ModelTerms:
    """The optional terms of one calibration (any may be absent).

    Attributes
    ----------
    temperature : dict of str to TemperaturePolynomial
        Sensor -> its polynomials.
    g_sensitivity : GSensitivity or None
    lever_arm : LeverArm or None
    mag_delay : MagDelay or None
    """

    temperature: dict = field(default_factory=dict)
    g_sensitivity: GSensitivity | None = None
    mag_delay: MagDelay | None = None
    lever_arm: LeverArm | None = None

    def __post_init__(self) -> None:
        unknown = sorted(set(self.temperature) - set(TEMPERATURE_SENSORS))
        if unknown:
            raise ValueError(
                f"temperature terms of unknown sensors {unknown}; expected {TEMPERATURE_SENSORS}"
            )

    @property
    def empty(self) -> bool:
        return not self.names()

    def names(self) -> list[str]:
        """The terms present, in :data:`TERMS` order."""
        return [t for t in TERMS if (bool(self.temperature) if t == "temperature" else
                                     getattr(self, t) is not None)]  # fmt: skip

    def to_dict(self) -> dict:
        out: dict = {}
        if self.temperature:
            out["temperature"] = {
                s: self.temperature[s].to_dict() for s in SENSORS if s in self.temperature
            }
        for term in ("g_sensitivity", "lever_arm", "mag_delay"):
            if getattr(self, term) is not None:
                out[term] = getattr(self, term).to_dict()
        return out

    @classmethod
    def from_dict(cls, d: dict) -> ModelTerms:
        unknown = sorted(set(d) - set(TERMS))
        if unknown:
            raise ValueError(f"calibration has unknown model terms {unknown}; known: {list(TERMS)}")
        return cls(
            {s: TemperaturePolynomial.from_dict(s, t) for s, t in d.get("temperature", {}).items()},
            GSensitivity.from_dict(d["g_sensitivity"]) if "g_sensitivity" in d else None,
            MagDelay.from_dict(d["mag_delay"]) if "mag_delay" in d else None,
            LeverArm.from_dict(d["lever_arm"]) if "lever_arm" in d else None,
        )
