"""The catalogue of effects: every effect of the simulator once, with what each scope of the
diagnosis does with it and the model term it feeds, read from the effects' specs.

A scope is a kind of session the diagnosis can score (:data:`SCOPES`: ``protocol``, ``static``,
``motion``, ``rests``, ``field_fit``). Each effect has one spec (:mod:`imucal.gap.library`)
stating, in every scope, either its estimator (an :class:`~imucal.gap.effects.EffectModel`,
with the statistics it moves) or the reason that scope cannot observe it (which the diagnosis
writes into ``diagnosis.json``). :func:`contract_violations` walks the specs against the
simulator's effects and the registered model terms, and the tests walk it. The effect behind
each model term of the closed loop is the term's own (:mod:`imucal.modelterms.registry`); the
contract checks that it is one the protocol's diagnosis can estimate.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from imucal.gap.library import LISTING, SCOPES, registered_specs, scope_library, spec_problems
from imucal.modelterms import registered_terms
from imucal.sim.effects import EFFECTS

__all__ = ["SCOPES", "Entry", "catalogue", "contract_violations", "term_of_effect"]


def term_of_effect() -> dict[str, str]:
    """Effect -> the registered model term that answers it (each term states its effect)."""
    return {term.effect: term.name for term in registered_terms()}


@dataclass(frozen=True)
class Entry:
    """One effect of the catalogue.

    Attributes
    ----------
    name : str
        The effect's canonical name (its simulator effect's).
    description : str
        What it is (its spec's description).
    kind : str
        ``systematic`` or ``spread`` (:data:`imucal.gap.library.KINDS`).
    estimated : dict of str to tuple
        Scope -> the ``(stage, sensor, statistic)`` locations its estimator there expects it
        to move; only the scopes that estimate it.
    not_observable : dict of str to str
        Scope -> why that scope cannot observe it.
    term : str or None
        The model term that answers it.
    """

    name: str
    description: str
    kind: str
    estimated: Mapping[str, tuple]
    not_observable: Mapping[str, str]
    term: str | None


def catalogue() -> dict[str, Entry]:
    """Every effect with a spec, with each scope's estimator or reason and its term."""
    out = {}
    for spec in registered_specs():
        out[spec.name] = Entry(
            name=spec.name,
            description=spec.description,
            kind=spec.kind,
            estimated={
                scope: tuple(spec.model(scope).signature)
                for scope in SCOPES
                if spec.model(scope) is not None
            },
            not_observable={
                scope: spec.reason(scope) for scope in SCOPES if spec.reason(scope) is not None
            },
            term=spec.term,
        )
    return out


def contract_violations() -> list[str]:
    """What the catalogue's contract finds missing: a simulator effect without a spec, a spec
    naming an effect the simulator does not have, a spec that does not state every scope
    exactly once (an estimator or a reason; :func:`imucal.gap.library.spec_problems`), a name
    in a scope's listing order (:data:`imucal.gap.library.LISTING`) without a spec, a model term
    whose effect the protocol's diagnosis cannot estimate. Empty when it holds."""
    specs = {spec.name: spec for spec in registered_specs()}
    problems = [f"{name!r}: an effect of the simulator without a spec" for name in EFFECTS
                if name not in specs]  # fmt: skip
    for name, spec in specs.items():
        if name not in EFFECTS:
            problems.append(f"{name!r}: a spec of no effect of the simulator")
        problems += spec_problems(spec)
    for scope, names in LISTING.items():
        problems += [f"{scope}: {name!r} is listed (LISTING) but has no spec"
                     for name in names if name not in specs]  # fmt: skip
    protocol = scope_library("protocol")
    for effect, term in term_of_effect().items():
        if effect not in protocol:
            problems.append(f"term {term!r}: its effect {effect!r} has no protocol estimator")
    return problems
