"""The registry of model terms: every term once, in the order the model applies them.

A term is a :class:`~imucal.modelterms.contract.ModelTerm` in a module of :mod:`imucal.modelterms`;
adding one to :data:`BUILT_IN` (or calling :func:`register`) is its whole registration, which
refuses a class with a part left abstract or a declaration the loops over the terms read missing
(:func:`declaration_problems`). The calibration, its dict form, the closed loop, the config's
section ``terms`` (:func:`settings_schema`), the report's coefficients, the exports' notes and the
catalogue's map from effects to terms (:func:`imucal.gap.catalogue.term_of_effect`) read the terms
from here.
"""

from __future__ import annotations

import copy
import dataclasses
import inspect
from collections.abc import Mapping

from imucal.modelterms.contract import SAMPLE_INPUTS, ModelTerm, ValueTerm
from imucal.modelterms.gsensitivity import GSensitivity
from imucal.modelterms.leverarm import LeverArm
from imucal.modelterms.magdelay import MagDelay
from imucal.modelterms.temperature import TemperatureTerm

#: The package's terms, in the order they are applied: the temperature on the reading (before
#: the matrix), the g-sensitivity with the calibrated specific force, the lever arm with the
#: rate corrected for it, the magnetometer delay with that rate.
BUILT_IN = (TemperatureTerm, GSensitivity, LeverArm, MagDelay)

_TERMS: dict[str, type[ModelTerm]] = {}


def declaration_problems(term: type[ModelTerm]) -> list[str]:
    """What is missing or malformed among the class attributes the calibration, apply, the
    closed loop, the report and the exports read of a term (empty when nothing is).

    Parameters
    ----------
    term : type
        A concrete subclass of :class:`ModelTerm`.

    Returns
    -------
    list of str
        One sentence per problem, naming the attribute and what was expected.
    """
    problems = []
    for attr in ("name", "effect", "switch_description"):
        if not isinstance(getattr(term, attr, None), str):
            problems.append(f"no {attr} (a str)")
    options = getattr(term, "options", None)
    if not isinstance(options, Mapping):
        problems.append("options is not a mapping of option -> JSON schema")
    else:
        for option, schema in options.items():
            if not (isinstance(option, str) and option.isidentifier()):
                problems.append(f"option {option!r} is not an identifier")
            elif not (isinstance(schema, Mapping) and "default" in schema
                      and isinstance(schema.get("description"), str)):  # fmt: skip
                problems.append(f"option {option!r} has no default and description in its schema")
    for attr in ("exported_by", "needs"):
        if not isinstance(getattr(term, attr, None), frozenset):
            problems.append(f"{attr} is not a frozenset")
    unknown = sorted(set(getattr(term, "needs", ())) - set(SAMPLE_INPUTS))
    if unknown:
        problems.append(f"needs {unknown}, not among the sample inputs {list(SAMPLE_INPUTS)}")
    residual = getattr(term, "heldout_residual", None)
    if residual is not None and not (isinstance(residual, str) and residual):
        problems.append("heldout_residual is neither None nor a non-empty str")
    if residual is None and term.heldout_rms.__func__ is not ModelTerm.heldout_rms.__func__:
        problems.append("reads a held-out RMS (heldout_rms) but declares no heldout_residual")
    if issubclass(term, ValueTerm):
        names = [f.name for f in dataclasses.fields(term)] if dataclasses.is_dataclass(term) else []
        for attr in ("value_field", "std_field"):
            if getattr(term, attr, None) not in names:
                problems.append(f"{attr} {getattr(term, attr, None)!r} is not one of its fields")
        if "method" not in names:
            problems.append("has no field 'method'")
        shape = getattr(term, "value_shape", None)
        if not (isinstance(shape, tuple) and all(isinstance(n, int) and n > 0 for n in shape)):
            problems.append(f"value_shape {shape!r} is not a tuple of positive ints")
        for attr in ("unit", "report_label"):
            if not (isinstance(getattr(term, attr, None), str) and getattr(term, attr)):
                problems.append(f"no {attr} (a non-empty str)")
    return problems


#: The values of a term's switch in the config: YAML's unquoted off/on arrive as False/True.
SWITCHES = ("off", "on", "auto")
#: The switch of a term the config does not set: estimated where the diagnosis accepts its effect.
DEFAULT_SWITCH = "auto"


def option_key(term: str, option: str) -> str:
    """The config key of a term's option (``terms.<term>_<option>``)."""
    return f"{term}_{option}"


def settings_schema() -> dict:
    """The JSON schema of the config's section ``terms``, made of the registered terms: per term
    its switch (:data:`SWITCHES`, default :data:`DEFAULT_SWITCH`) and its options (their schemas,
    with defaults and units, as the term declares them), nothing else."""
    properties = {}
    for term in registered_terms():
        properties[term.name] = {
            "type": ["string", "boolean"],
            "enum": [*SWITCHES, False, True],
            "default": DEFAULT_SWITCH,
            "description": f"{term.switch_description}: off, on, or auto (when the diagnosis "
            f"accepts {term.effect})",
        }
        for option, schema in term.options.items():
            properties[option_key(term.name, option)] = copy.deepcopy(dict(schema))
    return {
        "description": "optional model terms of the calibration, the closed loop (imucal.terms, "
        "docs/model-terms.md)",
        "type": "object",
        "additionalProperties": False,
        "default": {},
        "properties": properties,
    }


def register(term: type[ModelTerm]) -> type[ModelTerm]:
    """Add a term class at the end of the order (returned, so it can decorate the class).

    Raises
    ------
    ValueError
        If ``term`` is not a concrete :class:`ModelTerm`, lacks a class attribute the loops
        over the terms read (:func:`declaration_problems`), or its name is taken.
    """
    if not (inspect.isclass(term) and issubclass(term, ModelTerm)) or inspect.isabstract(term):
        raise ValueError(f"a model term must be a concrete subclass of ModelTerm, got {term!r}")
    problems = declaration_problems(term)
    if problems:
        raise ValueError(f"model term {term.__name__}: {'; '.join(problems)}")
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
