"""Switchable effects beyond the paper's error model: the hook interface and the registry.

An effect is a frozen dataclass whose fields are its parameters (SI units, names say the unit).
It changes the rendering at one or more levels, by overriding hooks that default to "no change":

==========================  =====================================================================
hook                        level
==========================  =====================================================================
``on_true_signals``         kinematics / true signals in B (lever arm, Earth rate, ...)
``on_readings``             sensor readings in SI before quantisation (drift, g-sensitivity, ...)
``on_packets``              the packet log: rows, timestamps, counter, extra columns
``on_truth``                the truth, once, before anything is rendered (``large_misalignment``)
``on_plan``                 the motion of a recording, before it is rendered (``placement_error``);
                            the segments written to truth.json stay the nominal ones
``on_true_signals``         kinematics / true signals in B (lever arm, Earth rate, ...)
``on_readings``             sensor readings in SI before quantisation (drift, g-sensitivity, ...)
``on_packets``              the packet log: rows, timestamps, counter, extra columns
``on_reference_clock``      the reference's clock (offset, drift)
``on_reference_times``      the instants a reference's samples are taken at, against their
                            nominal time stamps (``reference_jitter``)
``dataset_overrides``       keys of dataset.yaml the effect changes (e.g. ``range_counts``)
==========================  =====================================================================

The truth hook runs once, the IMU hooks for every IMU recording, the reference hooks once per reference. At each hook the effects run
in the order given, stably sorted by their class attribute ``priority`` (default 0; an effect that
must act last at its level, such as ``saturation`` at the ADC, has a higher one). Each effect draws its random numbers from its own stream (:meth:`RecordingContext.rng`
keyed by effect name and recording), so switching one effect on or off leaves the random numbers
of everything else unchanged.

Every effect also states its size: the class defaults are a *typical realistic magnitude*
(MEMS-class module, MTx-class reference; docs/simulator.md gives the sources),
:meth:`Effect.realistic` returns them, :meth:`Effect.magnitude` one headline number in SI with its
unit (what a blind check scores), and :meth:`Effect.scaled` the same effect with the headline
multiplied by a factor. Random draws an effect makes (e.g. per-position placement errors) are
recorded with :meth:`RecordingContext.record` and end up in ``truth.json["effects_realised"]``.
"""

from __future__ import annotations

import dataclasses
import zlib
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from imucal.calibration import ImuCalibration
from imucal.sim.motion import KinematicState, Motion
from imucal.sim.packets import PacketLog
from imucal.sim.reference import ReferenceClock
from imucal.sim.sensors import Signals

if TYPE_CHECKING:
    from imucal.sim.protocol import RecordingPlan
    from imucal.sim.truth import Truth

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
    motion : Motion or None
        The motion actually rendered (after ``on_plan``); None outside a session.
    calibration : ImuCalibration or None
        The true calibration (after ``on_truth``); None outside a session.
    realised : dict
        Effect name -> recording -> key -> value: random draws recorded by the effects
        (:meth:`record`); shared by all recordings of a session.
    """

    recording: str
    rate_hz: float
    session_start_s: float
    sensitivity: dict
    seed: int
    motion: Motion | None = None
    calibration: ImuCalibration | None = None
    realised: dict = field(default_factory=dict, compare=False)

    def rng(self, stream: str) -> np.random.Generator:
        return stream_rng(self.seed, f"{stream}/{self.recording}")

    def record(self, effect: str, key: str, value) -> None:
        """Keep a realised random draw (JSON-ready ``value``) of ``effect`` for truth.json."""
        self.realised.setdefault(effect, {}).setdefault(self.recording, {})[key] = value

    def require(self, effect: str, what: str):
        """``motion`` or ``calibration``, or a ValueError naming the effect that needs it."""
        value = getattr(self, what)
        if value is None:
            raise ValueError(
                f"effect {effect!r} needs the recording's {what}; render it with "
                "imucal.sim.simulate_session, which provides it"
            )
        return value


@dataclass(frozen=True)
class Magnitude:
    """Headline size of an effect: ``value`` in ``unit`` (SI), and what it means."""

    value: float
    unit: str
    meaning: str


@dataclass(frozen=True)
class Effect:
    """Base class: every hook returns its input unchanged."""

    name: ClassVar[str] = ""
    priority: ClassVar[int] = 0
    #: Parameters that scale linearly with :meth:`magnitude` (used by :meth:`scaled`).
    scalable: ClassVar[tuple[str, ...]] = ()

    def on_truth(self, truth: Truth) -> Truth:
        return truth

    def on_plan(self, plan: RecordingPlan, ctx: RecordingContext) -> RecordingPlan:
        return plan

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

    def on_reference_times(self, tau_s: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """The instants (s) the reference's samples stamped ``tau_s`` are taken at; ``rng`` is
        the effect's own stream."""
        return tau_s

    def dataset_overrides(self) -> dict:
        return {}

    def params(self) -> dict:
        """Parameter name -> value (JSON-ready)."""
        return dataclasses.asdict(self)

    @classmethod
    def realistic(cls) -> dict:
        """The typical realistic parameters (the class defaults), name -> value."""
        return dataclasses.asdict(cls())

    def magnitude(self) -> Magnitude:
        """The headline size of the effect in SI (see each effect's docstring)."""
        raise NotImplementedError(f"effect {self.name!r} does not define its magnitude")

    def scaled(self, factor: float) -> Effect:
        """The same effect with :meth:`magnitude` multiplied by ``factor`` (> 0).

        Multiplies the parameters listed in ``scalable``; the others are kept.

        Raises
        ------
        ValueError
            If ``factor`` is not > 0, the effect has no scalable parameter, or the scaled
            parameters are out of range (the effect's own check).
        """
        if not factor > 0:
            raise ValueError(f"effect {self.name!r}: scale factor must be > 0, got {factor}")
        if not self.scalable:
            raise ValueError(
                f"effect {self.name!r} has no parameter that scales its magnitude; "
                f"set its parameters {sorted(self.params())} instead"
            )
        return dataclasses.replace(
            self, **{k: _times(getattr(self, k), factor) for k in self.scalable}
        )


def _times(value, factor: float):
    """``value`` times ``factor``; a parameter of several values (per axis, a matrix's rows)
    element by element, keeping its nesting."""
    if isinstance(value, tuple):
        return tuple(_times(v, factor) for v in value)
    return value * factor


def axis_values(effect: str, key: str, value, shape: tuple = (3,)) -> tuple:
    """A per-axis (``shape`` (3,)) or per-element (``shape`` (3, 3)) parameter as nested tuples
    of floats; one number stands for the same value on every axis (or every diagonal element
    of a matrix, the others 0).

    Raises
    ------
    ValueError
        If ``value`` is not finite or has neither one element nor ``shape``.
    """
    a = np.asarray(value, dtype=float)
    if a.ndim == 0:
        a = np.full(shape, float(a)) if len(shape) == 1 else float(a) * np.eye(shape[0])
    elif a.size == int(np.prod(shape)):
        a = a.reshape(shape)
    else:
        raise ValueError(
            f"effect {effect!r}: parameter {key} has {a.size} values, expected 1 or "
            f"{int(np.prod(shape))} (shape {shape})"
        )
    if not np.all(np.isfinite(a)):
        raise ValueError(f"effect {effect!r}: parameter {key}={value!r} is not finite")
    return tuple(map(tuple, a.tolist())) if a.ndim == 2 else tuple(a.tolist())


def register(cls: type[Effect]) -> type[Effect]:
    """Class decorator: add an effect to :data:`EFFECTS` under ``cls.name``."""
    if not cls.name or cls.name in EFFECTS:
        raise ValueError(f"effect name {cls.name!r} is empty or registered twice")
    EFFECTS[cls.name] = cls
    return cls


def _coerce(effect: str, key: str, value, kind):
    if (kind if isinstance(kind, str) else kind.__name__) == "tuple":
        # several values (per axis, a matrix row by row): a list, a number for all, or in a
        # spec string separated by ';' (',' separates the parameters)
        if isinstance(value, str):
            parts = [v for v in value.replace(";", " ").split() if v]
            try:
                value = [float(v) for v in parts]
            except ValueError:
                raise ValueError(
                    f"effect {effect!r}: parameter {key}={value!r} is not numbers separated by ';'"
                ) from None
            return value[0] if len(value) == 1 else tuple(value)
        return value
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
