"""The effect model of the diagnosis: an effect's estimate from a session, and how one scope
observes the effect.

An :class:`EffectModel` holds, for one effect in one scope, an estimator of the simulator
effect's parameters from the session as that scope reads it, its signature (the statistics it
should move) and its physics gate. Every estimator works on physical quantities of the session
(packet counter, timestamps, rate-table run means, resting means, the temperature channel, the
reference clock), never on the simulator's internals, and returns parameters of the simulator's
effect of the same name so that the effect can be added to the twin. ``detect`` is a scalar
whose null distribution comes from running the same estimator on the twin replicas.

The effects themselves, each with its model or the reason it cannot be observed in every
scope, are the specs of :mod:`imucal.gap.library`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from imucal.sim.effects import make_effect


@dataclass(frozen=True)
class Estimate:
    """An effect's parameters estimated from a session.

    Attributes
    ----------
    params : dict
        Parameters of the simulator effect of the same name (SI).
    detect : float
        Detection statistic (scored against the replicas' values of the same estimator).
    evidence : dict
        Values the effect's physics gate reads beside the parameters (not simulator
        parameters), e.g. the magnetometer's lag in each phase.
    flags : tuple of str
        What the estimator refused to report as an estimate, with the reason (e.g. a warm-up
        fit beyond the recording's length); written with the effect into diagnosis.json.
    """

    params: dict
    detect: float
    evidence: dict = field(default_factory=dict)
    flags: tuple = ()


@dataclass(frozen=True)
class EffectModel:
    """One effect of the diagnosis's library.

    Attributes
    ----------
    name : str
        Canonical effect name (also the simulator effect's).
    estimate : callable
        ``(fit, half) -> Estimate or None`` (None: the session cannot show the effect).
    signature : tuple of (stage, sensor, statistic)
        Locations the effect should move (``'*'`` matches any sensor).
    description : str
    gate : callable, optional
        Physics check ``(estimate, null_estimates, z) -> str``: the reason the estimate cannot
        be this effect (empty when it can), with the null estimates (replicas) giving the
        estimator's spread and ``z`` the detection threshold.
    opens_gap : bool
        False for an effect the pipeline's exact model absorbs (reported, never attributed).
    spreads : bool
        Whether the effect adds spread to the twin's null rather than moving its mean (its
        spec's kind ``spread``, set when the spec is registered): its widening
        of the null counts at its own signature only.
    """

    name: str
    estimate: Callable
    signature: tuple
    description: str
    gate: Callable | None = None
    opens_gap: bool = True
    spreads: bool = False

    def simulator_effect(self, params: dict):
        return make_effect(self.name, **params)

    def matches(self, key: tuple) -> bool:
        return any(
            key[0] == stage and sensor in ("*", key[1]) and key[4] == stat
            for stage, sensor, stat in self.signature
        )
