"""The temperature term: polynomials of each sensor's bias and scale in the temperature.

``v = K (reading - o - b(dT)) / (1 + s(dT))`` elementwise inside the bracket, with
``dT = T - reference_c`` and the polynomials ``b(dT) = sum_k bias[k-1] dT^k``,
``s(dT) = sum_k scale[k-1] dT^k`` (k = 1 .. order; the constant term is the paper's bias and
matrix, which hold at ``reference_c``). Per sensor (accelerometer, gyroscope) and axis; a
sample outside the calibrated span is warned, and one farther out than the margin is corrected
at the temperature of the margin's edge (the polynomial is not extrapolated beyond it; PX4's
thermal compensation clamps the same way). The estimator is
:func:`imucal.gap.temperature.fit_temperature`.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from imucal.columns import SENSORS, SI_UNITS, TEMPERATURE_COLUMNS
from imucal.modelterms.contract import ModelTerm, ReportRow, Samples

#: Sensors a temperature polynomial may be estimated for.
TEMPERATURE_SENSORS = ("acc", "gyr")


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
        How far outside ``span_c`` (K) the polynomial is extrapolated (flagged); beyond it the
        drift is that at the margin's edge (flagged).
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
        """How many temperatures are outside the span, and how many beyond the margin.

        Parameters
        ----------
        temp_c : ndarray, shape (n,)
            Temperature of each sample (deg C), finite.
        source : str
            What the samples come from (file name), for the message.

        Returns
        -------
        dict
            ``outside_fraction`` (samples outside ``span_c``), ``max_outside_k`` (how far the
            farthest one is, K) and ``clamped_fraction`` (samples farther out than
            ``margin_c``, corrected at the margin's edge).
        """
        lo, hi = self.span_c
        beyond = np.maximum(lo - temp_c, temp_c - hi)
        worst = float(np.max(beyond)) if len(beyond) else 0.0
        return {
            "outside_fraction": float(np.mean(beyond > 0)) if len(beyond) else 0.0,
            "max_outside_k": max(worst, 0.0),
            "clamped_fraction": float(np.mean(beyond > self.margin_c)) if len(beyond) else 0.0,
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
        d_t = self._clamped(temp_c)[:, None] - self.reference_c
        bias = sum((c * d_t**k for k, c in enumerate(self.bias, 1)), np.zeros((len(d_t), 3)))
        scale = sum((c * d_t**k for k, c in enumerate(self.scale, 1)), np.zeros((len(d_t), 3)))
        return bias, scale

    def _clamped(self, temp_c: np.ndarray) -> np.ndarray:
        """The temperatures, those beyond the margin moved to its edge (deg C)."""
        lo, hi = self.span_c
        return np.clip(np.asarray(temp_c, dtype=float), lo - self.margin_c, hi + self.margin_c)

    def correct(self, bracket: np.ndarray, temp_c: np.ndarray) -> np.ndarray:
        """``(reading - bias - b(dT)) / (1 + s(dT))`` per axis (n, 3) from the bracket
        ``reading - bias``: the reading freed of the constant bias and the drift, at the scale
        of ``reference_c``."""
        drift, scale = self.drift(temp_c)
        return (bracket - drift) / (1.0 + scale)

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
        d_t = self._clamped(temp_c)[:, None] - self.reference_c
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
class TemperatureTerm(ModelTerm, Mapping):
    """The temperature polynomials of a calibration: sensor -> :class:`TemperaturePolynomial`.

    Attributes
    ----------
    polynomials : dict of str to TemperaturePolynomial
        Sensor ('acc', 'gyr') -> its polynomials; the term is a read-only mapping of them.
    """

    name = "temperature"
    effect = "temperature_drift"
    refits_session = True
    needs = frozenset({"temp_c"})
    heldout_residual = (
        "|a| - g of resting means, rate-table runs left out, each predicted from the others (m/s^2)"
    )
    switch_description = "temperature polynomials of bias and scale per axis"
    options = {
        "max_order": {
            "type": "integer", "minimum": 1, "default": 3,
            "description": "highest order of a bias polynomial tried (the held-out test picks one)",
        },
        "min_span_c": {
            "type": "number", "exclusiveMinimum": 0, "default": 2.0,
            "description": "smallest temperature span of the resting segments for a polynomial (K)",
        },
        "margin_c": {
            "type": "number", "minimum": 0, "default": 1.0,
            "description": "how far outside the calibrated temperature span apply still "
            "calibrates, flagged (K); beyond it apply refuses",
        },
    }  # fmt: skip

    polynomials: Mapping[str, TemperaturePolynomial]

    def __post_init__(self) -> None:
        unknown = sorted(set(self.polynomials) - set(TEMPERATURE_SENSORS))
        if unknown:
            raise ValueError(
                f"temperature terms of unknown sensors {unknown}; expected {TEMPERATURE_SENSORS}"
            )
        for sensor, poly in self.polynomials.items():
            if poly.sensor != sensor:
                raise ValueError(
                    f"temperature term of {sensor!r} holds {poly.sensor!r}'s polynomial"
                )
        object.__setattr__(
            self, "polynomials", {s: self.polynomials[s] for s in SENSORS if s in self.polynomials}
        )

    def __getitem__(self, sensor: str) -> TemperaturePolynomial:
        return self.polynomials[sensor]

    def __iter__(self) -> Iterator[str]:
        return iter(self.polynomials)

    def __len__(self) -> int:
        return len(self.polynomials)

    @classmethod
    def heldout_rms(cls, evidence: Mapping) -> tuple[float, float, int] | None:
        """The accelerometer's held-out RMS of the orders without and with the term (the
        estimator's evidence per sensor, :func:`imucal.gap.temperature.fit_temperature`)."""
        acc = evidence.get("acc", {})
        if "heldout_rms" not in acc or "refused" in acc:
            return None
        rms = acc["heldout_rms"]
        return rms[acc["without"]], rms[acc["with"]], int(acc["segments"])

    def check(self, samples: Samples) -> dict:
        """Per sensor, the samples outside its calibrated span and beyond its margin.

        Raises
        ------
        ValueError
            Without a finite temperature per sample.
        """
        flags = {}
        for sensor, poly in self.polynomials.items():
            if samples.temp_c is None:
                raise ValueError(
                    f"{samples.source}: the calibration has a temperature term for {sensor}; the "
                    f"recording has no temperature column (expected one of "
                    f"{list(TEMPERATURE_COLUMNS)})"
                )
            temp = np.asarray(samples.temp_c, dtype=float)
            n = len(samples.readings[sensor])
            if temp.shape != (n,) or not np.all(np.isfinite(temp)):
                raise ValueError(
                    f"{samples.source}: the temperature must be a finite value per sample "
                    f"({n}), got shape {temp.shape}"
                )
            flags[sensor] = poly.check_span(temp, samples.source)
        return flags

    def flag_report(self, flags: Mapping, source: str) -> tuple[dict, list[str]]:
        """``temperature_outside_span`` (the flags of :meth:`check`), and a warning per sensor
        with samples outside its span: extrapolation is never silent."""
        warnings = [
            f"{source}: {100 * f['outside_fraction']:.1f} % of the samples are outside the "
            f"{sensor} calibration's temperature span (up to {f['max_outside_k']:.2f} K): "
            "extrapolated within the margin"
            + (
                f", {100 * f['clamped_fraction']:.1f} % beyond it corrected at the margin's edge"
                if f.get("clamped_fraction", 0) > 0
                else ""
            )
            for sensor, f in flags.items()
            if f["outside_fraction"] > 0
        ]
        return {"temperature_outside_span": flags}, warnings

    def correct_reading(self, sensor: str, bracket: np.ndarray, samples: Samples) -> np.ndarray:
        """``(bracket - b(dT)) / (1 + s(dT))``: the reading freed of the drift, at the scale of
        ``reference_c``."""
        poly = self.polynomials.get(sensor)
        return bracket if poly is None else poly.correct(bracket, samples.temp_c)

    def variance(
        self,
        values: Mapping[str, np.ndarray],
        brackets: Mapping[str, np.ndarray],
        samples: Samples,
    ) -> dict:
        return {
            s: poly.variance(samples.calibration[s].matrix, brackets[s], samples.temp_c)
            for s, poly in self.polynomials.items()
        }

    def to_dict(self) -> dict:
        return {s: poly.to_dict() for s, poly in self.polynomials.items()}

    @classmethod
    def from_dict(cls, d: Mapping) -> TemperatureTerm:
        return cls({s: TemperaturePolynomial.from_dict(s, t) for s, t in d.items()})

    def report_rows(self) -> list[ReportRow]:
        rows = []
        for sensor, poly in self.polynomials.items():
            d = poly.to_dict()
            for kind in ("bias", "scale"):
                for k, (c, sd) in enumerate(zip(d[kind], d[f"{kind}_std"], strict=True), 1):
                    rows.append(
                        ReportRow(f"temperature {sensor} {kind} dT^{k}", c, sd, d[f"{kind}_unit"])
                    )
        return rows
