"""Protocol simulator: renders a complete calibration session from a known truth.

Modules (one concept each): :mod:`.truth` (sensor errors, world, noise, presets), :mod:`.motion`
(analytic kinematics), :mod:`.protocol` (what happens when, true segments), :mod:`.sensors`
(true signals -> counts), :mod:`.packets` (the packet log / raw CSV rows), :mod:`.reference`
(the Xsens reference and its clock), :mod:`.effects` (switchable effects beyond the paper's
model), :mod:`.session` (render and write a dataset folder). See docs/simulator.md.
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
from imucal.sim.protocol import ProtocolConfig, RecordingPlan, Segment
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

__all__ = [
    "CANONICAL",
    "EFFECTS",
    "PRESETS",
    "REALISTIC",
    "SENSITIVITY",
    "Effect",
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
    "World",
    "evaluate_motion",
    "make_effect",
    "make_truth",
    "parse_effect",
    "plan_session",
    "preset_effects",
    "simulate",
    "simulate_session",
    "write_session",
]
