"""The registry of effect specs, and every per-scope table of the diagnosis derived from it.

A family module of :mod:`imucal.gap.library` registers its specs (:func:`register`) when it is
imported. What a scope estimates (:func:`scope_library`) and what it cannot observe, with the
reason (:func:`not_observable`), are read from the registered specs and nowhere else: the
diagnosis of each scope, the catalogue's contract (:mod:`imucal.gap.catalogue`) and the
detection sweep call these functions.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

from imucal.gap.effects import EffectModel
from imucal.gap.library.spec import SCOPES, EffectSpec, spec_problems

_SPECS: dict[str, EffectSpec] = {}

#: The order each scope lists its effects in: its estimated effects (the attribution's order
#: of candidates), then those it cannot observe (``not_observable`` in diagnosis.json). It is
#: the order the scopes' tables had before the effects became specs, kept so that results stay
#: byte-identical; an effect not listed follows, in the order the specs were registered.
LISTING = {
    "protocol": (
        "packet_loss", "timing_jitter", "time_offset", "lever_arm", "g_sensitivity",
        "earth_rotation", "saturation", "temperature_drift", "bias_instability",
        "scale_nonlinearity", "mag_latency", "platform_magnetic", "placement_error",
        "large_misalignment",
        "hand_tremor", "reference_jitter", "world_magnetic", "shock", "vibration",
    ),
    "static": (
        "timing_jitter", "bias_instability", "temperature_drift",
        "packet_loss", "time_offset", "mag_latency", "lever_arm", "g_sensitivity",
        "earth_rotation", "saturation", "scale_nonlinearity", "world_magnetic", "shock",
        "vibration", "hand_tremor", "platform_magnetic", "placement_error",
        "large_misalignment", "reference_jitter",
    ),
    "motion": (
        "g_sensitivity", "scale_nonlinearity", "reference_jitter", "world_magnetic", "shock",
        "vibration",
        "timing_jitter", "packet_loss", "bias_instability", "temperature_drift", "time_offset",
        "mag_latency", "lever_arm", "earth_rotation", "saturation", "hand_tremor",
        "placement_error", "large_misalignment", "platform_magnetic",
    ),
    "rests": (
        "timing_jitter",
        "packet_loss", "time_offset", "mag_latency", "lever_arm", "g_sensitivity",
        "earth_rotation", "saturation", "scale_nonlinearity", "world_magnetic", "shock",
        "vibration", "hand_tremor", "platform_magnetic", "placement_error",
        "large_misalignment", "reference_jitter", "bias_instability", "temperature_drift",
    ),
    "field_fit": (
        "packet_loss", "time_offset", "lever_arm", "g_sensitivity", "earth_rotation",
        "saturation", "scale_nonlinearity", "shock", "vibration", "hand_tremor",
        "platform_magnetic", "placement_error", "large_misalignment", "reference_jitter",
        "world_magnetic", "mag_latency", "timing_jitter", "bias_instability",
        "temperature_drift",
    ),
}  # fmt: skip


def register(spec: EffectSpec) -> EffectSpec:
    """Add an effect's spec (returned, so that a module can keep it under a name).

    Raises
    ------
    ValueError
        If the spec has a problem (:func:`~imucal.gap.library.spec.spec_problems`) or its name
        is taken.
    """
    if not isinstance(spec, EffectSpec):
        raise ValueError(f"an effect's spec must be an EffectSpec, got {spec!r}")
    problems = spec_problems(spec)
    if problems:
        raise ValueError(f"effect spec {spec.name!r}: {'; '.join(problems)}")
    if spec.name in _SPECS:
        raise ValueError(f"an effect spec named {spec.name!r} is registered already")
    # the scopes' models say whether the effect adds spread, as its kind does
    spreads = spec.kind == "spread"
    scopes = {
        scope: dataclasses.replace(entry, spreads=spreads)
        if isinstance(entry, EffectModel) and entry.spreads != spreads
        else entry
        for scope, entry in spec.scopes.items()
    }
    spec = dataclasses.replace(spec, scopes=scopes)
    _SPECS[spec.name] = spec
    return spec


def unregister(name: str) -> None:
    """Remove the spec of ``name`` (an effect registered for a test, for instance).

    Raises
    ------
    ValueError
        If no spec of that name is registered.
    """
    if _SPECS.pop(name, None) is None:
        raise ValueError(f"no effect spec named {name!r} is registered; known: {list(_SPECS)}")


def registered_specs() -> tuple[EffectSpec, ...]:
    """The registered specs, in the order they were registered."""
    return tuple(_SPECS.values())


def spec_of(name: str) -> EffectSpec:
    """The spec of the effect ``name``.

    Raises
    ------
    ValueError
        If no spec of that name is registered.
    """
    if name not in _SPECS:
        raise ValueError(f"unknown effect {name!r}; the specs are {list(_SPECS)}")
    return _SPECS[name]


def _listed(scope: str) -> list[EffectSpec]:
    """The registered specs in the order ``scope`` lists them (:data:`LISTING`)."""
    if scope not in SCOPES:
        raise ValueError(f"unknown scope {scope!r}; expected one of {SCOPES}")
    first = [_SPECS[name] for name in LISTING[scope] if name in _SPECS]
    return first + [s for s in _SPECS.values() if s.name not in LISTING[scope]]


def scope_library(scope: str) -> dict[str, EffectModel]:
    """The effects ``scope`` estimates: effect name -> its model there.

    Raises
    ------
    ValueError
        If ``scope`` is not one of :data:`~imucal.gap.library.spec.SCOPES`.
    """
    return {s.name: s.model(scope) for s in _listed(scope) if s.model(scope) is not None}


def not_observable(scope: str) -> dict[str, str]:
    """The effects ``scope`` cannot observe: effect name -> why.

    Raises
    ------
    ValueError
        If ``scope`` is not one of :data:`~imucal.gap.library.spec.SCOPES`.
    """
    return {s.name: s.reason(scope) for s in _listed(scope) if s.reason(scope) is not None}


def library(exclude: Sequence[str] = ()) -> dict[str, EffectModel]:
    """The full protocol's library without the effects named in ``exclude`` (the unknown-effect
    check).

    Raises
    ------
    ValueError
        If ``exclude`` names an effect the protocol's library does not hold.
    """
    protocol = scope_library("protocol")
    unknown = sorted(set(exclude) - set(protocol))
    if unknown:
        raise ValueError(f"cannot exclude {unknown}: not in the library {sorted(protocol)}")
    return {k: v for k, v in protocol.items() if k not in exclude}
