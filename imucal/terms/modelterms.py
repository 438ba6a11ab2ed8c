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

Each term is one module of :mod:`imucal.terms.model` keeping the contract of
:class:`imucal.terms.term.ModelTerm` (its correction, variance, dict form, report rows, export
note and estimator), registered in :mod:`imucal.terms.registry`, whose order is the order above.
This module holds :class:`ModelTerms`, the terms of one calibration, and re-exports the terms'
classes.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import Any

from imucal.terms.model.gsensitivity import GSensitivity
from imucal.terms.model.leverarm import LEVER_ARM_DIFF_S, LeverArm, angular_acceleration
from imucal.terms.model.magdelay import MagDelay
from imucal.terms.model.temperature import (
    TEMPERATURE_SENSORS,
    TemperaturePolynomial,
    TemperatureTerm,
)
from imucal.terms.registry import term_class, term_names
from imucal.terms.term import ModelTerm

__all__ = [
    "LEVER_ARM_DIFF_S",
    "TEMPERATURE_SENSORS",
    "TERMS",
    "GSensitivity",
    "LeverArm",
    "MagDelay",
    "ModelTerms",
    "TemperaturePolynomial",
    "TemperatureTerm",
    "angular_acceleration",
]

#: Names of the package's optional terms, in the order they are applied
#: (:data:`imucal.terms.registry.BUILT_IN`).
TERMS = term_names()


class ModelTerms(Mapping):
    """The optional terms of one calibration, name -> term, in the registry's order (any may
    be absent); read-only.

    ``ModelTerms(g_sensitivity=GSensitivity(...), ...)``: each keyword a registered term's
    name, its value an instance of that term's class, or None (absent). A term that holds
    nothing (a temperature term without polynomials) is absent too. A term is also an
    attribute, None when absent: ``terms.lever_arm``.

    Raises
    ------
    ValueError
        For a name no term is registered under, or a value of another class.
    """

    __slots__ = ("_terms",)

    def __init__(self, **terms: ModelTerm | None) -> None:
        unknown = sorted(set(terms) - set(term_names()))
        if unknown:
            raise ValueError(f"unknown model terms {unknown}; known: {list(term_names())}")
        for name, term in terms.items():
            cls = term_class(name)
            if term is not None and not isinstance(term, cls):
                raise ValueError(
                    f"model term {name!r} must be a {cls.__name__}, got {type(term).__name__}"
                )
        kept = {n: terms[n] for n in term_names() if terms.get(n) is not None and terms[n]}
        object.__setattr__(self, "_terms", kept)

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError("ModelTerms is read-only; build a new one")

    def __getattr__(self, name: str) -> ModelTerm | None:
        if name in term_names():
            return self._terms.get(name)
        raise AttributeError(f"ModelTerms has no attribute {name!r}")

    def __getitem__(self, name: str) -> ModelTerm:
        return self._terms[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._terms)

    def __len__(self) -> int:
        return len(self._terms)

    def __reduce__(self) -> tuple:
        return _from_terms, (dict(self._terms),)

    def __repr__(self) -> str:
        return f"ModelTerms({', '.join(f'{n}={t!r}' for n, t in self._terms.items())})"

    @property
    def empty(self) -> bool:
        return not self._terms

    def names(self) -> list[str]:
        """The terms present, in the order they are applied."""
        return list(self._terms)

    def to_dict(self) -> dict:
        return {name: term.to_dict() for name, term in self._terms.items()}

    @classmethod
    def from_dict(cls, d: Mapping) -> ModelTerms:
        unknown = sorted(set(d) - set(term_names()))
        if unknown:
            raise ValueError(
                f"calibration has unknown model terms {unknown}; known: {list(term_names())}"
            )
        return cls(**{name: term_class(name).from_dict(entry) for name, entry in d.items()})


def _from_terms(terms: dict) -> ModelTerms:
    """A :class:`ModelTerms` from name -> term (unpickling)."""
    return ModelTerms(**terms)
