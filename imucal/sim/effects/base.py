"""Switchable effects beyond the paper's error model: the hook interface and the registry.

An effect is a frozen dataclass whose fields are its parameters (SI units, names say the unit).
It changes the rendering at one or more levels, by overriding hooks that default to "no change":

==========================  =====================================================================
hook                        level
==========================  =====================================================================
``on_true_signals``         kinematics / true signals in B (lever arm, Earth rate, ...)
``on_readings``             sensor readings in SI before quantisation (drift, g-sensitivity, ...)
``on_packets``              the packet log: rows, timestamps, counter, extra columns
``on_reference_clock``      the reference's clock (offset, drift)
``dataset_overrides``       keys of dataset.yaml the effect changes (e.g. ``range_counts``)
==========================  =====================================================================

The IMU hooks run for every IMU recording, the reference hook once. At each hook the effects run
in the order given, stably sorted by their class attribute ``priority`` (default 0; an effect that
must act last at its level, such as ``saturation`` at the ADC, has a higher one). Each effect draws its random numbers from its own stream (:meth:`RecordingContext.rng`
keyed by effect name and recording), so switching one effect on or off leaves the random numbers
of everything else unchanged.
"""

from __future__ import annotations

import dataclasses
import zlib
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from imucal.sim.motion import KinematicState
from imucal.sim.packets import PacketLog
from imucal.sim.reference import ReferenceClock
from imucal.sim.sensors import Signals

#: Canonical effect name -> effect class.
EFFECTS: dict[str, type[Effect]] = {}


def stream_rng(seed: int, stream: str) -> np.random.Generator:
    """An independent random generator for the named stream of a seeded session."""
    return np.random.default_rng(
        np.random.SeedSequence(seed, spawn_key=(zlib.crc32(stream.encode()),))
    )


@dataclass(frozen=True)
class RecordingContext:
    """What an effect may know about the recording it acts on.

    Attributes
    ----------
    recording : str
    rate_hz : float
        Packet (acc/gyro) rate; module sample ``k`` is at ``k / rate_hz`` s.
    session_start_s : float
        Start of this recording on the session clock (s since the start of the first recording).
    sensitivity : dict
        SI unit per count, per sensor.
    seed : int
    """

    recording: str
    rate_hz: float
    session_start_s: float
    sensitivity: dict
    seed: int

    def rng(self, stream: str) -> np.random.Generator:
        return stream_rng(self.seed, f"{stream}/{self.recording}")


@dataclass(frozen=True)
class Effect:
    """Base class: every hook returns its input unchanged."""

    name: ClassVar[str] = ""
    priority: ClassVar[int] = 0

    def on_true_signals(
        self, signals: Signals, state: KinematicState, ctx: RecordingContext
    ) -> Signals:
        return signals

    def on_readings(
        self, readings: Signals, true: Signals, state: KinematicState, ctx: RecordingContext
    ) -> Signals:
        return readings

    def on_packets(self, log: PacketLog, ctx: RecordingContext) -> PacketLog:
        return log

    def on_reference_clock(self, clock: ReferenceClock) -> ReferenceClock:
        return clock

    def dataset_overrides(self) -> dict:
        return {}

    def params(self) -> dict:
        """Parameter name -> value (JSON-ready)."""
        return dataclasses.asdict(self)


def register(cls: type[Effect]) -> type[Effect]:
    """Class decorator: add an effect to :data:`EFFECTS` under ``cls.name``."""
    if not cls.name or cls.name in EFFECTS:
        raise ValueError(f"effect name {cls.name!r} is empty or registered twice")
    EFFECTS[cls.name] = cls
    return cls


def _coerce(effect: str, key: str, value, kind):
    target = {"float": float, "int": int, "str": str}.get(
        kind if isinstance(kind, str) else kind.__name__
    )
    try:
        if target is int and isinstance(value, str):
            return int(float(value)) if float(value).is_integer() else int(value)
        return target(value)
    except (TypeError, ValueError):
        raise ValueError(
            f"effect {effect!r}: parameter {key}={value!r} is not a valid {target.__name__}"
        ) from None


def make_effect(name: str, **params) -> Effect:
    """Instantiate a registered effect, converting string values to the parameter types.

    Raises
    ------
    ValueError
        For an unknown effect name, an unknown parameter, or a value of the wrong type.
    """
    if name not in EFFECTS:
        raise ValueError(f"unknown effect {name!r}; expected one of {sorted(EFFECTS)}")
    cls = EFFECTS[name]
    fields = {f.name: f.type for f in dataclasses.fields(cls)}
    unknown = sorted(set(params) - set(fields))
    if unknown:
        raise ValueError(f"effect {name!r} has no parameters {unknown}; it has {sorted(fields)}")
    return cls(**{k: _coerce(name, k, v, fields[k]) for k, v in params.items()})


def parse_effect(spec: str) -> Effect:
    """Parse ``"name"`` or ``"name:key=value,key=value"`` (the CLI's ``--effect``)."""
    name, _, rest = spec.partition(":")
    params = {}
    for item in filter(None, (s.strip() for s in rest.split(","))):
        key, eq, value = item.partition("=")
        if not eq or not key:
            raise ValueError(f"effect spec {spec!r}: expected key=value, got {item!r}")
        params[key.strip()] = value.strip()
    return make_effect(name.strip(), **params)
