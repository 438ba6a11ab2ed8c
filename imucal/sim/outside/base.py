"""The registry of the effects outside the diagnosis's library."""

from __future__ import annotations

import dataclasses

from imucal.sim.effects.base import EFFECTS, Effect, make_effect

#: Name -> class of the effects outside the library (none of them is in ``EFFECTS``).
OUTSIDE: dict[str, type[Effect]] = {}


def register_outside(cls: type[Effect]) -> type[Effect]:
    """Class decorator: add an effect to :data:`OUTSIDE` under ``cls.name``.

    Raises
    ------
    ValueError
        If the name is empty, taken here, or an effect of the library's.
    """
    if not cls.name or cls.name in OUTSIDE or cls.name in EFFECTS:
        raise ValueError(f"outside effect name {cls.name!r} is empty, taken, or a library effect")
    OUTSIDE[cls.name] = cls
    return cls


def make_outside(name: str, **params) -> Effect:
    """An effect of the library (:func:`imucal.sim.effects.make_effect`) or of :data:`OUTSIDE`,
    by name, with its parameters (strings converted as ``make_effect`` does).

    Raises
    ------
    ValueError
        For a name in neither registry, an unknown parameter or a value of the wrong type.
    """
    if name in EFFECTS:
        return make_effect(name, **params)
    if name not in OUTSIDE:
        raise ValueError(
            f"unknown effect {name!r}; expected one of {sorted(EFFECTS)} or, outside the "
            f"library, {sorted(OUTSIDE)}"
        )
    cls = OUTSIDE[name]
    fields = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(params) - fields)
    if unknown:
        raise ValueError(f"effect {name!r} has no parameters {unknown}; it has {sorted(fields)}")
    return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in params.items()})
