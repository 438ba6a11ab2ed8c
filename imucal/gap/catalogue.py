"""The catalogue of effects: every effect of the simulator once, with what each scope of the
diagnosis does with it and the model term it feeds.

A scope is a kind of session the diagnosis can score: ``protocol`` (the paper's whole protocol,
:data:`imucal.gap.effects.LIBRARY`), ``static`` (a static recording, or the rest or pose that
stands in for one, :data:`imucal.gap.static.STATIC_LIBRARY`), ``motion`` (recordings with an
orientation reference, :func:`imucal.gap.motion.motion_library`) and ``rests`` (a session's
short rests pooled, :data:`imucal.gap.rests.REST_LIBRARY`) and ``field_fit`` (a magnetometer
turned without any rest: no effect, :data:`imucal.gap.fieldfit.FIELD_FIT_NOT_OBSERVABLE`). In every scope an effect has
either an estimator (its :class:`~imucal.gap.effects.EffectModel` there, with the statistics it
moves) or the reason that scope cannot observe it (the scope's not-observable table, which the
diagnosis writes into ``diagnosis.json``); :func:`contract_violations` lists every effect that
has neither or both, and the tests walk it. The effect behind each model term of the closed
loop is the term's own (:mod:`imucal.modelterms.registry`); the contract checks that it is one the
protocol's diagnosis can estimate.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from imucal.modelterms import registered_terms

#: The scopes of the diagnosis, in the order the report lists them.
SCOPES = ("protocol", "static", "motion", "rests", "field_fit")

#: Effects the full protocol's diagnosis cannot show, and why.
PROTOCOL_NOT_OBSERVABLE = {
    "hand_tremor": "the twin replays the protocol's plan on the platform; a hand's tremor changes "
    "how the protocol is carried out, which the segmentation reports (holds held by hand)",
    "reference_jitter": "the MT Manager reference is aligned by its clock (offset and drift), "
    "not compared sample by sample with the gyroscope",
    "world_magnetic": "the platform turns the module about a point of its own: a field fixed in "
    "the world near it adds to the lab's field, which the ellipsoid and the alignment take as "
    "it is (platform_magnetic is the field that moves with the platform)",
    "shock": "the protocol's statistics are segment means and fits, not residuals against an "
    "independent attitude; a knock within a pose splits it at the static detector",
    "vibration": "no spectral statistic in the protocol's gap map; a vibration within a pose "
    "raises the noise the static detector's threshold is set from",
}


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
        What it is (the first line of the simulator effect's docstring).
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
    estimated: Mapping[str, tuple]
    not_observable: Mapping[str, str]
    term: str | None


def scope_libraries() -> dict[str, tuple[Mapping, Mapping]]:
    """Scope -> (its library: effect -> EffectModel, its not-observable table: effect ->
    reason)."""
    from imucal.gap.effects import LIBRARY
    from imucal.gap.fieldfit import FIELD_FIT_NOT_OBSERVABLE
    from imucal.gap.motion import MOTION_NOT_OBSERVABLE, motion_library
    from imucal.gap.rests import REST_LIBRARY, REST_NOT_OBSERVABLE
    from imucal.gap.static import NOT_OBSERVABLE, STATIC_LIBRARY

    return {
        "protocol": (LIBRARY, PROTOCOL_NOT_OBSERVABLE),
        "static": (STATIC_LIBRARY, NOT_OBSERVABLE),
        "motion": (motion_library(), MOTION_NOT_OBSERVABLE),
        "rests": (REST_LIBRARY, REST_NOT_OBSERVABLE),
        "field_fit": ({}, FIELD_FIT_NOT_OBSERVABLE),
    }


def catalogue() -> dict[str, Entry]:
    """Every effect of the simulator with each scope's estimator or reason and its term."""
    from imucal.sim.effects import EFFECTS

    libraries = scope_libraries()
    terms = term_of_effect()
    out = {}
    for name, cls in EFFECTS.items():
        doc = (cls.__doc__ or "").strip().splitlines()
        out[name] = Entry(
            name=name,
            description=doc[0] if doc else "",
            estimated={
                scope: tuple(library[name].signature)
                for scope, (library, _) in libraries.items()
                if name in library
            },
            not_observable={
                scope: reasons[name] for scope, (_, reasons) in libraries.items() if name in reasons
            },
            term=terms.get(name),
        )
    return out


def contract_violations() -> list[str]:
    """What the catalogue's contract finds missing: an effect with neither an estimator nor a
    reason in a scope, or both; a table naming an effect the simulator does not have; a model
    term whose effect the protocol's diagnosis cannot estimate. Empty when it holds."""
    from imucal.sim.effects import EFFECTS

    problems = []
    for scope, (library, reasons) in scope_libraries().items():
        for name in sorted(set(library) | set(reasons)):
            if name not in EFFECTS:
                problems.append(f"{scope}: {name!r} is not an effect of the simulator")
        for name in EFFECTS:
            if name in library and name in reasons:
                problems.append(f"{scope}: {name!r} has an estimator and a reason")
            elif name not in library and name not in reasons:
                problems.append(f"{scope}: {name!r} has neither an estimator nor a reason")
    protocol = scope_libraries()["protocol"][0]
    for effect, term in term_of_effect().items():
        if effect not in protocol:
            problems.append(f"term {term!r}: its effect {effect!r} has no protocol estimator")
    return problems
