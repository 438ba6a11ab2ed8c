"""Effects beyond the paper's error model, by canonical name (see :mod:`.base` for the hooks)."""

from imucal.sim.effects.base import (
    EFFECTS,
    Effect,
    RecordingContext,
    make_effect,
    parse_effect,
    register,
    stream_rng,
)
from imucal.sim.effects.kinematic import EarthRotation, LeverArm
from imucal.sim.effects.sensor import GSensitivity, Saturation, TemperatureDrift
from imucal.sim.effects.timing import PacketLoss, TimeOffset, TimingJitter

__all__ = [
    "EFFECTS",
    "EarthRotation",
    "Effect",
    "GSensitivity",
    "LeverArm",
    "PacketLoss",
    "RecordingContext",
    "Saturation",
    "TemperatureDrift",
    "TimeOffset",
    "TimingJitter",
    "make_effect",
    "parse_effect",
    "register",
    "stream_rng",
]
