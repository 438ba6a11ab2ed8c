"""The effects of the diagnosis: one spec per effect, one module per family of effects.

Every effect of the simulator has one :class:`~imucal.gap.library.spec.EffectSpec`: its name,
what it is, its kind (``systematic`` or ``spread``) and, in every scope of the diagnosis
(:data:`~imucal.gap.library.spec.SCOPES`), either its model there (the estimator, the
statistics it moves, its physics gate: an :class:`~imucal.gap.effects.EffectModel`) or the
reason the scope cannot observe it. The specs live in the family modules (:data:`FAMILIES`)
with the estimators that read nothing but the session; estimators that share the statistics of
a scope stay beside them (:mod:`imucal.gap.motionstats`, :mod:`imucal.gap.worldfield`,
:mod:`imucal.gap.disturbance`) and are referenced. A family module registers its specs
(:func:`register`) when it is imported; every per-scope table (:func:`scope_library`,
:func:`not_observable`, the protocol's :func:`library`) is read from the registry, and the
catalogue's contract (:func:`imucal.gap.catalogue.contract_violations`) walks the specs.

Adding an effect is one module: its simulator model registered with
:func:`imucal.sim.effects.register` and its spec registered with :func:`register`, with an
estimator in at least one scope and the reason in the others.
"""

# each family registers its specs when it is imported
from imucal.gap.library import (
    acquisition,
    handling,
    inertial,
    magnetic,
    mounting,
    noise,
    thermal,
)
from imucal.gap.library.registry import (
    LISTING,
    library,
    not_observable,
    register,
    registered_specs,
    scope_library,
    spec_of,
    unregister,
)
from imucal.gap.library.spec import KINDS, SCOPES, EffectSpec, spec_problems

#: The family modules, each holding the specs of its effects.
FAMILIES = (acquisition, handling, inertial, magnetic, mounting, noise, thermal)

__all__ = [
    "FAMILIES",
    "KINDS",
    "LISTING",
    "SCOPES",
    "EffectSpec",
    "library",
    "not_observable",
    "register",
    "registered_specs",
    "scope_library",
    "spec_of",
    "spec_problems",
    "unregister",
]
