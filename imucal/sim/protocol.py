"""The calibration protocol: what happens when in each recording, with its true segments.

The timing mimics the independent conformance session (``../shared/data/conformance/clean``):

* ``rotation3d`` (~80 s): static with z up; phase x (two turns about B's x with cosine spin-up
  and spin-down); pause; transition +90 deg about z (vertical); pause; phase y (two turns about
  y); pause; transition -90 deg about z; pause; phase z (two turns about z); pause.
* ``cube`` (~120 s): 12 static positions (6 faces, 6 on a 45-deg V-block) joined by smooth
  hand-handling motions with a little wobble.
* ``ratetable`` (~330 s): for each axis, a handling motion that makes it vertical, then one run
  per rate (spin-up, constant rate, spin-down, pause); the 0 deg/s run is static for as long.
* ``static``: one long static interval.

Segment labels and kinds follow docs/architecture.md. Times are on the recording's module clock
(sample ``k`` is taken at ``k / rate``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from imucal.columns import AXES
from imucal.sim.motion import Motion, Piece, hold, move, turn

#: The 12 "up" directions of the cube (in B): 6 faces, then 6 on the V-block at 45 deg.
CUBE_UP_B = (
    (0, 0, 1), (0, 0, -1), (1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0),
    (0, 1, 1), (0, 1, -1), (1, 0, 1), (1, 0, -1), (1, 1, 0), (1, -1, 0),
)  # fmt: skip


@dataclass(frozen=True)
class Segment:
    """A true segment of a recording (one row of the segments table).

    Attributes
    ----------
    recording, label, kind : str
        As in docs/architecture.md (kind: 'static', 'phase', 'transition', 'position', 'run').
    start_s, end_s : float
        Module time (s). For a ``run`` these bound the constant-rate plateau; the whole spin
        (spin-up to end of spin-down) is ``motion_start_s``..``motion_end_s``. For phases and
        transitions they bound the whole rotation, ramps included.
    axis : str or None
        Rotation axis of B ('x', 'y', 'z'); None when not a rotation.
    rate_dps : float or None
        Nominal table rate (runs only), deg/s.
    sense : int
        +1 / -1 for a rotation, 0 otherwise.
    turns : float or None
        Signed number of turns about ``axis`` between ``start_s`` and ``end_s``.
    motion_start_s, motion_end_s : float or None
        Runs only, see above.
    """

    recording: str
    label: str
    kind: str
    start_s: float
    end_s: float
    axis: str | None = None
    rate_dps: float | None = None
    sense: int = 0
    turns: float | None = None
    motion_start_s: float | None = None
    motion_end_s: float | None = None

    def to_dict(self) -> dict:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


@dataclass(frozen=True)
class RecordingPlan:
    """Motion of one recording and its true segments."""

    recording: str
    motion: Motion
    segments: tuple[Segment, ...]


@dataclass(frozen=True)
class ProtocolConfig:
    """Timing of the protocol (s, deg/s). Ranges ``(low, high)`` are drawn from the seed.

    Attributes
    ----------
    rotation3d_static_s : float
        Initial static interval of ``rotation3d``.
    phase_turns : tuple of float
        Signed turns of phases x, y, z.
    phase_rate_dps : tuple of float
        Plateau rate of phases x, y, z.
    phase_ramp_s : float
        Spin-up and spin-down time of a phase.
    pause_s : float
        Static pause between the parts of ``rotation3d``.
    transition_s : float
        Duration of each 90-deg transition about z.
    cube_position_s, cube_move_s : tuple of float
        Ranges of the static time per position and of a handling motion.
    cube_wobble_deg : float
        Largest wobble amplitude of a handling motion.
    ratetable_axes : tuple of str
    rates_dps : tuple of float
    run_plateau_s, run_ramp_s, run_pause_s : float
        Constant-rate time, spin-up (= spin-down) time, pause after each run.
    mount_s : float
        Handling motion that re-mounts the module on the rate table.
    static_s : float
        Length of the ``static`` recording.
    """

    rotation3d_static_s: float = 11.0
    phase_turns: tuple[float, float, float] = (2.0, -2.0, 2.0)
    phase_rate_dps: tuple[float, float, float] = (50.0, 50.0, 60.0)
    phase_ramp_s: float = 1.5
    pause_s: float = 3.5
    transition_s: float = 3.7
    cube_position_s: tuple[float, float] = (6.0, 8.0)
    cube_move_s: tuple[float, float] = (2.5, 3.5)
    cube_wobble_deg: float = 3.0
    ratetable_axes: tuple[str, ...] = AXES
    rates_dps: tuple[float, ...] = (-400, -300, -200, -100, 0, 100, 200, 300, 400)
    run_plateau_s: float = 7.0
    run_ramp_s: float = 1.0
    run_pause_s: float = 2.0
    mount_s: float = 3.5
    static_s: float = 360.0

    def __post_init__(self) -> None:
        if not self.static_s > 0:
            raise ValueError(f"static_s must be > 0 s, got {self.static_s}")
        bad = [a for a in self.ratetable_axes if a not in AXES]
        if bad:
            raise ValueError(f"ratetable_axes {bad} not among {AXES}")


def _unit(axis: str) -> np.ndarray:
    return np.eye(3)[AXES.index(axis)]


def _upright(up_b: np.ndarray, heading_rad: float) -> Rotation:
    """Orientation (B -> world) with ``up_b`` pointing up and the given heading about world z."""
    up = np.asarray(up_b, dtype=float) / np.linalg.norm(up_b)
    align, _ = Rotation.align_vectors([[0.0, 0.0, 1.0]], [up])
    return Rotation.from_euler("z", heading_rad) * align


class _Timeline:
    """Accumulates pieces and segments of one recording."""

    def __init__(self, recording: str, orientation: Rotation) -> None:
        self.recording = recording
        self.pieces: list[Piece] = []
        self.segments: list[Segment] = []
        self.orientation = orientation
        self.t = 0.0

    def add(self, piece: Piece) -> Piece:
        self.pieces.append(piece)
        self.orientation = piece.end
        self.t = piece.end_s
        return piece

    def segment(self, piece: Piece, label: str, kind: str, **fields) -> None:
        self.segments.append(
            Segment(self.recording, label, kind, piece.start_s, piece.end_s, **fields)
        )

    def plan(self) -> RecordingPlan:
        return RecordingPlan(self.recording, Motion(tuple(self.pieces)), tuple(self.segments))


def plan_rotation3d(config: ProtocolConfig, rng: np.random.Generator) -> RecordingPlan:
    """The 3-D platform recording: phases x, y, z about B's axes with two transitions about z."""
    tl = _Timeline("rotation3d", _upright((0, 0, 1), rng.uniform(0, 2 * np.pi)))
    statics = iter(f"s{i:02d}" for i in range(1, 100))
    tl.segment(
        tl.add(hold(0.0, config.rotation3d_static_s, tl.orientation)), next(statics), "static"
    )
    transitions = {"x": 90.0, "y": -90.0}
    for i, axis in enumerate(AXES):
        turns = config.phase_turns[i]
        rate = np.radians(config.phase_rate_dps[i])
        angle = 2 * np.pi * turns
        duration = abs(angle) / rate + config.phase_ramp_s
        piece = turn(tl.t, duration, tl.orientation, _unit(axis), angle, config.phase_ramp_s)
        tl.segment(tl.add(piece), axis, "phase", axis=axis, sense=int(np.sign(turns)), turns=turns)
        tl.segment(tl.add(hold(tl.t, config.pause_s, tl.orientation)), next(statics), "static")
        if axis in transitions:
            deg = transitions[axis]
            piece = turn(tl.t, config.transition_s, tl.orientation, _unit("z"), np.radians(deg))
            label = f"t{i + 1:02d}"
            tl.segment(
                tl.add(piece),
                label,
                "transition",
                axis="z",
                sense=int(np.sign(deg)),
                turns=deg / 360,
            )
            tl.segment(tl.add(hold(tl.t, config.pause_s, tl.orientation)), next(statics), "static")
    return tl.plan()


def _handle(tl: _Timeline, target: Rotation, duration_s: float, wobble_deg: float, rng) -> Piece:
    """Append a hand-handling motion to ``target`` with a random small wobble."""
    return tl.add(
        move(
            tl.t,
            duration_s,
            tl.orientation,
            target,
            wobble_axis_b=rng.normal(size=3),
            wobble_rad=np.radians(rng.uniform(0.3, 1.0) * wobble_deg),
            wobble_cycles=rng.uniform(0.5, 2.0),
        )
    )


def plan_cube(config: ProtocolConfig, rng: np.random.Generator) -> RecordingPlan:
    """The cube recording: 12 static positions ``p01``..``p12`` joined by handling motions."""
    targets = [_upright(up, rng.uniform(0, 2 * np.pi)) for up in CUBE_UP_B]
    tl = _Timeline("cube", targets[0])
    for i, target in enumerate(targets):
        if i > 0:
            _handle(tl, target, rng.uniform(*config.cube_move_s), config.cube_wobble_deg, rng)
        piece = hold(tl.t, rng.uniform(*config.cube_position_s), target)
        tl.segment(tl.add(piece), f"p{i + 1:02d}", "position")
    return tl.plan()


def plan_ratetable(config: ProtocolConfig, rng: np.random.Generator) -> RecordingPlan:
    """The rate-table recording: per axis a re-mount, then one run per rate (labels ``x-400``...)."""
    tl = _Timeline("ratetable", _upright((0, 0, 1), rng.uniform(0, 2 * np.pi)))
    tl.add(hold(0.0, config.run_pause_s, tl.orientation))
    tr, tc = config.run_ramp_s, config.run_plateau_s
    for axis in config.ratetable_axes:
        target = _upright(_unit(axis), rng.uniform(0, 2 * np.pi))
        _handle(tl, target, config.mount_s, config.cube_wobble_deg, rng)
        tl.add(hold(tl.t, config.run_pause_s, tl.orientation))
        for rate_dps in config.rates_dps:
            duration = 2 * tr + tc
            if rate_dps == 0:
                piece = tl.add(hold(tl.t, duration, tl.orientation))
            else:
                angle = np.radians(rate_dps) * (tr + tc)
                piece = tl.add(turn(tl.t, duration, tl.orientation, _unit(axis), angle, tr))
            tl.segments.append(
                Segment(
                    "ratetable",
                    f"{axis}{int(rate_dps):+d}",
                    "run",
                    piece.start_s + tr,
                    piece.start_s + tr + tc,
                    axis=axis,
                    rate_dps=float(rate_dps),
                    sense=int(np.sign(rate_dps)),
                    turns=float(rate_dps) * tc / 360.0,
                    motion_start_s=piece.start_s,
                    motion_end_s=piece.end_s,
                )
            )
            tl.add(hold(tl.t, config.run_pause_s, tl.orientation))
    return tl.plan()


def plan_static(config: ProtocolConfig, rng: np.random.Generator) -> RecordingPlan:
    """The long static recording (z up), one segment ``s01``."""
    tl = _Timeline("static", _upright((0, 0, 1), rng.uniform(0, 2 * np.pi)))
    tl.segment(tl.add(hold(0.0, config.static_s, tl.orientation)), "s01", "static")
    return tl.plan()


@dataclass(frozen=True)
class TumbleConfig:
    """Timing of a module turned by hand from one orientation to the next (s, deg).

    Attributes
    ----------
    poses : int
        Orientations held, each drawn uniformly over all rotations.
    hold_s, move_s : tuple of float
        Ranges of the pause at each orientation and of the turn to the next.
    rest_s : float
        The module lies on the table this long before the hand picks it up.
    wobble_deg : float
        Largest wobble amplitude of a turn.
    """

    poses: int = 26
    hold_s: tuple[float, float] = (0.5, 0.9)
    move_s: tuple[float, float] = (1.0, 2.0)
    rest_s: float = 5.0
    wobble_deg: float = 3.0

    def __post_init__(self) -> None:
        if self.poses < 1:
            raise ValueError(f"poses must be >= 1, got {self.poses}")
        if not 0 < self.hold_s[0] <= self.hold_s[1] or not 0 < self.move_s[0] <= self.move_s[1]:
            raise ValueError(
                f"hold_s {self.hold_s} and move_s {self.move_s} must be ranges 0 < low <= high s"
            )


def plan_tumble(config: TumbleConfig, rng: np.random.Generator) -> RecordingPlan:
    """A hand-tumbled ``poses`` recording: a rest on the table (``s01``, static), then
    ``config.poses`` orientations ``p01``.. (kind ``position``) held briefly, joined by
    handling turns."""
    tl = _Timeline("poses", _upright((0, 0, 1), rng.uniform(0, 2 * np.pi)))
    tl.segment(tl.add(hold(0.0, config.rest_s, tl.orientation)), "s01", "static")
    for i in range(config.poses):
        target = Rotation.random(random_state=rng)
        _handle(tl, target, rng.uniform(*config.move_s), config.wobble_deg, rng)
        piece = hold(tl.t, rng.uniform(*config.hold_s), target)
        tl.segment(tl.add(piece), f"p{i + 1:02d}", "position")
    return tl.plan()


#: Planner of each IMU recording, in protocol order.
PLANNERS = {
    "rotation3d": plan_rotation3d,
    "cube": plan_cube,
    "ratetable": plan_ratetable,
    "static": plan_static,
}
