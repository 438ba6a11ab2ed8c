"""Effects beyond the paper's error model, by canonical name (see :mod:`.base` for the hooks).

:data:`REALISTIC` maps every effect name to its typical realistic parameters (the class
defaults); ``make_effect(name).magnitude()`` gives the headline size in SI.
"""

from imucal.sim.effects.base import (
    EFFECTS,
    Effect,
    Magnitude,
    RecordingContext,
    make_effect,
    parse_effect,
    register,
    stream_rng,
)
from imucal.sim.effects.disturbance import Shock, Vibration, WorldMagnetic
from imucal.sim.effects.handling import HandTremor
from imucal.sim.effects.kinematic import EarthRotation, LeverArm
from imucal.sim.effects.magnetic import MagLatency, PlatformMagnetic, platform_yaw
from imucal.sim.effects.mounting import PLACEMENT_CONVENTION, LargeMisalignment, PlacementError
from imucal.sim.effects.noise import BiasInstability
from imucal.sim.effects.sensor import (
    GSensitivity,
    Saturation,
    ScaleNonlinearity,
    TemperatureDrift,
)
from imucal.sim.effects.timing import (
    ClockDrift,
    PacketLoss,
    ReferenceJitter,
    TimeOffset,
    TimingJitter,
)

#: The canonical effects of the diagnosis, in the order of docs/simulator.md.
CANONICAL = (
    "temperature_drift",
    "bias_instability",
    "g_sensitivity",
    "scale_nonlinearity",
    "saturation",
    "time_offset",
    "clock_drift",
    "packet_loss",
    "timing_jitter",
    "mag_latency",
    "platform_magnetic",
    "lever_arm",
    "earth_rotation",
    "placement_error",
    "large_misalignment",
)

#: Effects that change how the protocol is carried out rather than the sensor or the setup
#: (a module held by hand); the gap diagnosis has no model of them.
PROTOCOL_EFFECTS = ("hand_tremor",)

#: Effects of a reference system rather than of the module; the diagnosis models them where the
#: reference is compared sample by sample with the gyroscope (:mod:`imucal.gap.motion`).
REFERENCE_EFFECTS = ("reference_jitter",)

#: Effects a hand-held or robot-borne module meets; the diagnosis models them where a reference
#: gives the module's attitude (:mod:`imucal.gap.motion`).
MOTION_EFFECTS = ("world_magnetic", "shock", "vibration")

#: Effect name -> its typical realistic parameters (MEMS-class module, MTx-class reference).
REALISTIC = {
    name: EFFECTS[name].realistic()
    for name in CANONICAL + PROTOCOL_EFFECTS + REFERENCE_EFFECTS + MOTION_EFFECTS
}

__all__ = [
    "CANONICAL",
    "EFFECTS",
    "PLACEMENT_CONVENTION",
    "PROTOCOL_EFFECTS",
    "REALISTIC",
    "REFERENCE_EFFECTS",
    "BiasInstability",
    "ClockDrift",
    "EarthRotation",
    "Effect",
    "GSensitivity",
    "HandTremor",
    "LargeMisalignment",
    "LeverArm",
    "MOTION_EFFECTS",
    "MagLatency",
    "Magnitude",
    "PacketLoss",
    "ReferenceJitter",
    "PlacementError",
    "PlatformMagnetic",
    "RecordingContext",
    "Saturation",
    "ScaleNonlinearity",
    "Shock",
    "TemperatureDrift",
    "TimeOffset",
    "TimingJitter",
    "Vibration",
    "WorldMagnetic",
    "make_effect",
    "parse_effect",
    "platform_yaw",
    "register",
    "stream_rng",
]
