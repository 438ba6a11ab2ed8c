"""Protocol simulator: renders a complete calibration session from a known truth.

Modules (one concept each): :mod:`.truth` (sensor errors, world, noise, presets), :mod:`.motion`
(analytic kinematics), :mod:`.protocol` (what happens when, true segments), :mod:`.sensors`
(true signals -> counts), :mod:`.packets` (the packet log / raw CSV rows), :mod:`.reference`
(the Xsens reference and its clock), :mod:`.effects` (switchable effects beyond the paper's
model), :mod:`.session` (render and write a dataset folder), :mod:`.tumble` (a module tumbled
by hand with brief pauses). See docs/simulator.md.
"""

from imucal.sim.effects import (
    CANONICAL,
    EFFECTS,
    REALISTIC,
    Effect,
    Magnitude,
    make_effect,
    parse_effect,
)
from imucal.sim.motion import KinematicState, Motion, Piece, evaluate_motion
from imucal.sim.protocol import ProtocolConfig, RecordingPlan, Segment, TumbleConfig
from imucal.sim.reference import ReferenceClock
from imucal.sim.session import (
    SENSITIVITY,
    Session,
    plan_session,
    preset_effects,
    simulate,
    simulate_session,
    write_session,
)
from imucal.sim.truth import PRESETS, Truth, World, make_truth
from imucal.sim.tumble import HandTumble, simulate_tumble

__all__ = [
    "CANONICAL",
    "EFFECTS",
    "PRESETS",
    "REALISTIC",
    "SENSITIVITY",
    "Effect",
    "HandTumble",
    "KinematicState",
    "Magnitude",
    "Motion",
    "Piece",
    "ProtocolConfig",
    "RecordingPlan",
    "ReferenceClock",
    "Segment",
    "Session",
    "Truth",
    "TumbleConfig",
    "World",
    "evaluate_motion",
    "make_effect",
    "make_truth",
    "parse_effect",
    "plan_session",
    "preset_effects",
    "simulate",
    "simulate_session",
    "simulate_tumble",
    "write_session",
]
