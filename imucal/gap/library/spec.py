"""The spec of an effect: everything the diagnosis knows of one effect, in every scope.

An effect of the simulator (:data:`imucal.sim.effects.EFFECTS`) has one :class:`EffectSpec`: its
name (the simulator effect's), a line saying what it is, its kind (:data:`KINDS`) and, for every
scope of the diagnosis (:data:`SCOPES`), either how that scope observes it (an
:class:`~imucal.gap.effects.EffectModel`: the estimator there, the statistics it moves, its
physics gate) or the reason the scope cannot observe it. The model term that answers it is read
from the registered terms (:attr:`EffectSpec.term`), each of which states its effect.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from imucal.gap.effects import EffectModel
from imucal.modelterms import registered_terms

#: The scopes of the diagnosis, in the order the report lists them: ``protocol`` (the paper's
#: whole protocol, :func:`imucal.gap.diagnosis.diagnose`), ``static`` (a static recording, or
#: the rest or pose that stands in for one, :mod:`imucal.gap.static`), ``motion`` (recordings
#: with an orientation reference, :mod:`imucal.gap.motion`), ``rests`` (a session's short rests
#: pooled, :mod:`imucal.gap.rests`) and ``field_fit`` (a magnetometer turned without any rest,
#: :mod:`imucal.gap.fieldfit`).
SCOPES = ("protocol", "static", "motion", "rests", "field_fit")

#: The kinds of effect: ``systematic`` moves the statistics of the twin's replicas (a bias, a
#: lever arm, a delay), ``spread`` adds spread to the twin's null rather than moving its mean
#: (a zero-mean random process drawn afresh in every replica: a wander, a jitter, a tremor).
KINDS = ("systematic", "spread")


@dataclass(frozen=True)
class EffectSpec:
    """One effect of the diagnosis.

    Attributes
    ----------
    name : str
        The simulator effect's name.
    description : str
        What the effect is, in one line.
    kind : str
        One of :data:`KINDS`.
    scopes : mapping of str to EffectModel or str
        Every scope of :data:`SCOPES` -> the effect's model there (its ``name`` the spec's), or
        the reason that scope cannot observe it.
    """

    name: str
    description: str
    kind: str
    scopes: Mapping[str, EffectModel | str]

    def model(self, scope: str) -> EffectModel | None:
        """The effect's model in ``scope``, None where the scope cannot observe it."""
        entry = self.scopes[scope]
        return entry if isinstance(entry, EffectModel) else None

    def reason(self, scope: str) -> str | None:
        """Why ``scope`` cannot observe the effect, None where it has a model there."""
        entry = self.scopes[scope]
        return entry if isinstance(entry, str) else None

    @property
    def term(self) -> str | None:
        """The registered model term that answers the effect (None: no term does)."""
        return next((t.name for t in registered_terms() if t.effect == self.name), None)


def spec_problems(spec: EffectSpec) -> list[str]:
    """What a spec lacks or gets wrong (empty when nothing): a kind outside :data:`KINDS`, a
    scope of :data:`SCOPES` without a model or a reason, a scope it names that the diagnosis
    does not have, a model named after another effect, an empty reason.

    Parameters
    ----------
    spec : EffectSpec

    Returns
    -------
    list of str
        One sentence per problem, naming the effect and the scope.
    """
    name = spec.name
    problems = []
    if spec.kind not in KINDS:
        problems.append(f"{name!r}: kind {spec.kind!r} is not one of {KINDS}")
    if not (isinstance(spec.description, str) and spec.description):
        problems.append(f"{name!r}: no description")
    for scope in SCOPES:
        entry = spec.scopes.get(scope)
        if entry is None:
            problems.append(f"{scope}: {name!r} has neither an estimator nor a reason")
        elif isinstance(entry, EffectModel):
            if entry.name != name:
                problems.append(f"{scope}: {name!r} has the model of {entry.name!r}")
        elif not (isinstance(entry, str) and entry):
            problems.append(f"{scope}: {name!r} has neither a model nor a reason: {entry!r}")
    for scope in sorted(set(spec.scopes) - set(SCOPES)):
        problems.append(f"{scope}: {name!r} names a scope the diagnosis does not have")
    return problems
