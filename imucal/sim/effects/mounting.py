"""Effects on how the module sits on its fixtures and in its housing: placement_error,
large_misalignment."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from imucal import errormodel
from imucal.calibration import ImuCalibration, SensorCalibration
from imucal.columns import SENSORS
from imucal.sim.effects.base import Effect, Magnitude, RecordingContext, register
from imucal.sim.motion import Motion, Piece
from imucal.sim.protocol import RecordingPlan
from imucal.sim.truth import Truth

#: How the realised placement errors relate the rendered orientation to the nominal one.
PLACEMENT_CONVENTION = "R_actual = R_nominal * Rot(rotvec_rad), rotvec in B (rad)"


def _retarget(piece: Piece, start: Rotation, end: Rotation) -> Piece:
    """A handling piece that goes from ``start`` to ``end`` with the same timing and wobble."""
    rotvec = (start.inv() * end).as_rotvec()
    angle = float(np.linalg.norm(rotvec))
    axis = rotvec / angle if angle > 0 else np.array([0.0, 0.0, 1.0])
    return dataclasses.replace(piece, start=start, axis_b=axis, angle_rad=angle)


@register
@dataclass(frozen=True)
class PlacementError(Effect):
    """The cube, V-block and rate-table mountings are not exactly the nominal orientations.

    * ``cube``: every static position is held at ``R_nominal Exp(delta_p)`` with ``delta_p``
      (rotation vector in B) drawn per position, each component normal with std
      ``cube_sigma_deg``; the handling motions join the perturbed positions.
    * ``ratetable``: each re-mounting (one per table axis) puts the module at
      ``R_nominal Exp(delta_m)`` (std ``table_sigma_deg``); the table still spins about the
      world vertical, so in B the spin axis is ``Exp(-delta_m) e_axis`` instead of ``e_axis``
      (the rate-table axes are not the nominal ones).

    ``rotation3d`` (the platform defines B) and ``static`` are unchanged. The segments in
    truth.json stay the nominal ones (the pipeline knows only those); the draws go to
    ``truth.json["effects_realised"]["placement_error"]``: ``{"cube": {"p01": rotvec_rad, ...},
    "ratetable": {"x": rotvec_rad, ...}}`` with :data:`PLACEMENT_CONVENTION`.

    A placement error is a rotation: ``|a|`` is unchanged, its direction in B turns by the tilt
    part of ``delta`` (1 deg -> 17 mg perpendicular to g), so a norm-based fit (eq. 32) stays
    clean while an attitude-based one does not (effects.md #15).

    Parameters
    ----------
    cube_sigma_deg : float
        Std per axis of a cube / V-block placement (deg), >= 0. Realistic: 0.3 (hand placed,
        0.1-1 deg).
    table_sigma_deg : float
        Std per axis of a rate-table mounting (deg), >= 0. Realistic: 0.3.
    """

    name = "placement_error"
    scalable = ("cube_sigma_deg", "table_sigma_deg")
    cube_sigma_deg: float = 0.3
    table_sigma_deg: float = 0.3

    def __post_init__(self) -> None:
        for key in ("cube_sigma_deg", "table_sigma_deg"):
            if not getattr(self, key) >= 0:
                raise ValueError(
                    f"placement_error {key} must be >= 0 deg, got {getattr(self, key)}"
                )

    def on_plan(self, plan: RecordingPlan, ctx: RecordingContext) -> RecordingPlan:
        if plan.recording == "cube":
            motion = self._cube(plan, ctx)
        elif plan.recording == "ratetable":
            motion = self._ratetable(plan, ctx)
        else:
            return plan
        return dataclasses.replace(plan, motion=motion)

    def _cube(self, plan: RecordingPlan, ctx: RecordingContext) -> Motion:
        pieces = plan.motion.pieces
        holds = [i for i, p in enumerate(pieces) if p.profile == "hold"]
        labels = [s.label for s in plan.segments if s.kind == "position"]
        if len(labels) != len(holds):
            raise ValueError(
                f"placement_error: cube plan has {len(holds)} holds but {len(labels)} positions"
            )
        sigma = np.radians(self.cube_sigma_deg)
        deltas = ctx.rng(f"effect/{self.name}").normal(0.0, sigma, (len(holds), 3))
        actual = {i: pieces[i].start * Rotation.from_rotvec(d) for i, d in zip(holds, deltas)}
        out = []
        for i, piece in enumerate(pieces):
            if i in actual:
                out.append(dataclasses.replace(piece, start=actual[i]))
            else:  # a handling motion between two positions
                out.append(_retarget(piece, actual[i - 1], actual[i + 1]))
        for label, d in zip(labels, deltas):
            ctx.record(self.name, label, d.tolist())
        return Motion(tuple(out))

    def _ratetable(self, plan: RecordingPlan, ctx: RecordingContext) -> Motion:
        sigma = np.radians(self.table_sigma_deg)
        rng = ctx.rng(f"effect/{self.name}")
        axes = iter(dict.fromkeys(s.axis for s in plan.segments if s.kind == "run"))
        current = plan.motion.pieces[0].start
        delta = Rotation.identity()
        out = []
        for piece in plan.motion.pieces:
            if piece.profile == "smooth":  # a re-mounting: a new placement error
                d = rng.normal(0.0, sigma, 3)
                ctx.record(self.name, next(axes), d.tolist())
                delta = Rotation.from_rotvec(d)
                new = _retarget(piece, current, piece.end * delta)
            elif piece.profile == "ramp":  # a run: the table spins about the world vertical
                new = dataclasses.replace(
                    piece, start=current, axis_b=delta.inv().apply(piece.axis_b)
                )
            else:
                new = dataclasses.replace(piece, start=current)
            out.append(new)
            current = new.end
        return Motion(tuple(out))

    def magnitude(self) -> Magnitude:
        return Magnitude(
            float(np.radians(self.cube_sigma_deg)), "rad", "std per axis of a cube placement"
        )


@register
@dataclass(frozen=True)
class LargeMisalignment(Effect):
    """Misalignment rotations ``T_R`` of several degrees, where the small-angle form fails.

    Replaces the truth's ``alpha`` of each sensor by a rotation vector of the same direction
    and the given angle, keeping scale and non-orthogonality (the calibration matrix is
    recomposed with the exact rotation); truth.json then holds the large ``alpha``.

    The simulator and :func:`imucal.errormodel.rotation_matrix` use the exact rotation, so the
    pipeline's exact variant recovers it; the gap opens only where a stage uses the paper's
    small-angle variant (eq. 5, ``exact=False``): its error is second order, about
    ``theta^2 / 2`` (5 deg -> 0.38 %, 10 deg -> 1.5 %), and leaks into scale and
    non-orthogonality (effects.md #16).

    Parameters
    ----------
    acc_deg, gyr_deg, mag_deg : float
        Misalignment angle of each sensor (deg), >= 0; 0 keeps the truth's ``alpha``.
        Realistic for a module assembled by hand or a separate magnetometer chip: 5, 5, 8.
    """

    name = "large_misalignment"
    scalable = ("acc_deg", "gyr_deg", "mag_deg")
    acc_deg: float = 5.0
    gyr_deg: float = 5.0
    mag_deg: float = 8.0

    def __post_init__(self) -> None:
        for s in SENSORS:
            if not getattr(self, f"{s}_deg") >= 0:
                raise ValueError(
                    f"large_misalignment {s}_deg must be >= 0 deg, got {getattr(self, f'{s}_deg')}"
                )

    def on_truth(self, truth: Truth) -> Truth:
        sensors = []
        for s in SENSORS:
            cal = truth.calibration.sensor(s)
            angle = np.radians(getattr(self, f"{s}_deg"))
            if angle == 0:
                sensors.append(cal)
                continue
            dec = cal.decomposition
            norm = np.linalg.norm(dec.alpha_rad)
            if norm == 0:
                raise ValueError(
                    f"large_misalignment: the truth's {s} alpha is zero, so it has no direction "
                    f"to scale to {getattr(self, f'{s}_deg')} deg"
                )
            alpha = dec.alpha_rad / norm * angle
            matrix = errormodel.compose(dec.scale, dec.xi_rad, alpha)
            sensors.append(
                SensorCalibration(
                    s, cal.bias, matrix, cal.unit, method=f"{cal.method}, {self.name}"
                )
            )
        return dataclasses.replace(truth, calibration=ImuCalibration(*sensors))

    def magnitude(self) -> Magnitude:
        angle = max(self.acc_deg, self.gyr_deg, self.mag_deg)
        return Magnitude(float(np.radians(angle)), "rad", "largest misalignment angle |alpha|")
