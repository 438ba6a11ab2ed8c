"""The model terms' estimators, found by the term's name.

A term's class (:mod:`imucal.modelterms`) is part of the model at the bottom of the layers; its
estimator needs the session fitted with the paper's model (:class:`imucal.pipeline.full.SessionFit`)
and lives up here. The closed loop asks :func:`estimator_of` for the estimator of each term it
includes. A term added outside the package registers its class
(:func:`imucal.modelterms.register`) and its estimator (:func:`register_estimator`) in one module.

An estimator is ``estimator(fit, **options) -> (term or None, evidence)``: ``options`` are the
term's own config settings (:attr:`imucal.modelterms.ModelTerm.options`); the term is None when
the data do not support it (``evidence['refused']`` says why); ``evidence`` is the JSON-ready
record of the estimate (held-out RMS, what was used, or the refusal).
"""

from __future__ import annotations

from collections.abc import Callable

from imucal.gap.temperature import fit_temperature
from imucal.modelterms import ModelTerm, TemperatureTerm, term_names
from imucal.pipeline.full import SessionFit
from imucal.terms.gsensitivity import fit_g_sensitivity
from imucal.terms.leverarm import fit_lever_arm
from imucal.terms.magdelay import fit_mag_delay

Estimator = Callable[..., tuple[ModelTerm | None, dict]]

_ESTIMATORS: dict[str, Estimator] = {}


def fit_temperature_term(
    fit: SessionFit, *, max_order: int, min_span_c: float, margin_c: float
) -> tuple[TemperatureTerm | None, dict]:
    """The temperature term of a session: the polynomials of
    :func:`imucal.gap.temperature.fit_temperature` (the estimator the diagnosis shares), None
    when no sensor takes one."""
    polys, evidence = fit_temperature(
        fit, max_order=max_order, min_span_c=min_span_c, margin_c=margin_c
    )
    return (TemperatureTerm(polys) if polys else None), evidence


def register_estimator(term: str, estimator: Estimator) -> Estimator:
    """Register the estimator of the registered term ``term`` (returned).

    Raises
    ------
    ValueError
        If no term of that name is registered, or it has an estimator already.
    """
    if term not in term_names():
        raise ValueError(f"no model term named {term!r} is registered; known: {list(term_names())}")
    if term in _ESTIMATORS:
        raise ValueError(f"the model term {term!r} has an estimator already")
    _ESTIMATORS[term] = estimator
    return estimator


def unregister_estimator(term: str) -> None:
    """Remove the estimator of ``term`` (one registered for a test, for instance).

    Raises
    ------
    ValueError
        If ``term`` has no estimator.
    """
    if _ESTIMATORS.pop(term, None) is None:
        raise ValueError(f"the model term {term!r} has no estimator")


def estimator_of(term: str) -> Estimator:
    """The estimator of the term ``term``.

    Raises
    ------
    ValueError
        If the term has none (naming the terms that have one).
    """
    if term not in _ESTIMATORS:
        raise ValueError(
            f"the model term {term!r} has no estimator; terms with one: {sorted(_ESTIMATORS)}"
        )
    return _ESTIMATORS[term]


def missing_estimators() -> list[str]:
    """The registered terms without an estimator (empty when every term has one)."""
    return [name for name in term_names() if name not in _ESTIMATORS]


for _term, _estimator in (
    ("temperature", fit_temperature_term),
    ("g_sensitivity", fit_g_sensitivity),
    ("lever_arm", fit_lever_arm),
    ("mag_delay", fit_mag_delay),
):
    register_estimator(_term, _estimator)
