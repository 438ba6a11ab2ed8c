"""The registry of model terms: every term once, in the order the model applies them.

A term is a :class:`~imucal.terms.term.ModelTerm` in a module of :mod:`imucal.terms.model`;
adding one to :data:`BUILT_IN` is its whole registration. The calibration, its dict form, the
closed loop, the report's coefficients, the exports' notes and the catalogue's map from effects
to terms (:data:`imucal.gap.catalogue.TERM_OF_EFFECT`) read the terms from here.
"""

from __future__ import annotations

import inspect

from imucal.terms.model.gsensitivity import GSensitivity
from imucal.terms.model.leverarm import LeverArm
from imucal.terms.model.magdelay import MagDelay
from imucal.terms.model.temperature import TemperatureTerm
from imucal.terms.term import ModelTerm

#: The package's terms, in the order they are applied: the temperature on the reading (before
#: the matrix), the g-sensitivity with the calibrated specific force, the lever arm with the
#: rate corrected for it, the magnetometer delay with that rate.
BUILT_IN = (TemperatureTerm, GSensitivity, LeverArm, MagDelay)

_TERMS: dict[str, type[ModelTerm]] = {}


def register(term: type[ModelTerm]) -> type[ModelTerm]:
    """Add a term class at the end of the order (returned, so it can decorate the class).

    Raises
    ------
    ValueError
        If ``term`` is not a concrete :class:`ModelTerm` with a ``name`` and an ``effect``, or
        its name is taken.
    """
    if not (inspect.isclass(term) and issubclass(term, ModelTerm)) or inspect.isabstract(term):
        raise ValueError(f"a model term must be a concrete subclass of ModelTerm, got {term!r}")
    for attr in ("name", "effect"):
        if not isinstance(getattr(term, attr, None), str):
            raise ValueError(f"model term {term.__name__} has no {attr} (a str)")
    if term.name in _TERMS:
        raise ValueError(f"a model term named {term.name!r} is registered already")
    _TERMS[term.name] = term
    return term


def unregister(name: str) -> None:
    """Remove the term ``name`` (a term registered for a test, for instance).

    Raises
    ------
    ValueError
        If no term of that name is registered.
    """
    if _TERMS.pop(name, None) is None:
        raise ValueError(f"no model term named {name!r} is registered; known: {list(_TERMS)}")


def registered_terms() -> tuple[type[ModelTerm], ...]:
    """The registered term classes, in the order the model applies them."""
    return tuple(_TERMS.values())


def term_names() -> tuple[str, ...]:
    """The registered terms' names, in the order the model applies them."""
    return tuple(_TERMS)


def term_class(name: str) -> type[ModelTerm]:
    """The class of the term ``name``.

    Raises
    ------
    ValueError
        If no term of that name is registered.
    """
    if name not in _TERMS:
        raise ValueError(f"unknown model term {name!r}; known: {list(_TERMS)}")
    return _TERMS[name]


for _term in BUILT_IN:
    register(_term)
