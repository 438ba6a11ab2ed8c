"""Mounting: the module, cube and rate-table mountings not where the protocol puts them.

``placement_error`` and ``large_misalignment``: their specs and the full protocol's estimators
(the cube positions' tilts that the accelerometer and the magnetometer see together, and the
fitted misalignment angles).
"""

from __future__ import annotations

import numpy as np

from imucal import errormodel
from imucal.columns import SENSORS
from imucal.gap import locations as loc
from imucal.gap.effects import EffectModel, Estimate
from imucal.gap.library.registry import register
from imucal.gap.library.spec import EffectSpec
from imucal.pipeline.full import SessionFit


def estimate_placement_error(fit: SessionFit, half) -> Estimate | None:
    """Placement std per axis (deg) from the cube positions' tilts that the accelerometer
    and the magnetometer see together, and the rate-table mountings' tilts (their rest runs).

    A placement error is a rigid rotation of the cube: it turns gravity and the field together
    in B. The accelerometer's tilts alone (:func:`imucal.gap.locations.cube_direction_residuals`)
    are also made by an accelerometer bias or temperature drift, which leaves the field where
    it was. So the cube's std is the covariance of the two sensors' tilts about the axis that
    changes the angle between them (:func:`imucal.gap.locations.cube_joint_tilts`):
    ``sigma^2 = sum(a f) / sum(1 - h_ii)``, at least 0; the error and noise of either sensor
    alone add nothing to it on average. None for a cube held by hand (its poses are the hand's,
    and the session has no direction statistic) or with a field at fewer than five nominal
    positions.

    Returns
    -------
    Estimate or None
        ``cube_sigma_deg``, ``table_sigma_deg`` (deg, std per axis); detection: the cube's.
    """
    if "cube" in fit.extra["options"].held_by_hand:
        return None
    acc, field, free = loc.cube_joint_tilts(fit, half)
    if not len(free):
        return None
    cube = float(np.degrees(np.sqrt(max(np.sum(acc * field) / np.sum(free), 0.0))))
    tilts = loc.table_mount_tilts(fit)
    table = float(np.degrees(np.sqrt(np.sum(tilts**2) / (2 * len(tilts))))) if len(tilts) else cube
    evidence = {"acc_tilt": acc, "field_tilt": field, "free": free}
    return Estimate({"cube_sigma_deg": cube, "table_sigma_deg": table}, cube, evidence)


#: Level of the test that the accelerometer's and the field's tilts move together
#: (:func:`placement_gate`).
TOGETHER_P = 0.01


def placement_gate(est: Estimate, null: list, z: float) -> str:
    """A rigid turn of the cube tilts gravity and the field alike: the positions' tilts of the
    accelerometer and of the magnetometer (``evidence``) must be correlated, one-sided at
    :data:`TOGETHER_P` (Student's t of the correlation on the positions' free degrees of
    freedom less one). An error of the accelerometer alone (a scale that depends on the
    force's sign, a cross-axis product) tilts its directions and leaves the field's as they
    were: it can raise the covariance's estimate through its own size, never the correlation.
    The reason the estimate is not a placement, or ''."""
    from scipy import stats as sps

    a, f = (np.asarray(est.evidence.get(k, ()), dtype=float) for k in ("acc_tilt", "field_tilt"))
    dof = int(round(float(np.sum(est.evidence.get("free", ()))))) - 1
    if len(a) < 3 or dof < 2 or not (np.any(a) and np.any(f)):
        return ""
    r = float(np.sum(a * f) / np.sqrt(np.sum(a * a) * np.sum(f * f)))
    t = r * np.sqrt(dof / max(1 - r * r, 1e-12))
    p = float(sps.t.sf(t, dof))
    if p > TOGETHER_P:
        return (f"the accelerometer's tilts and the field's do not move together (correlation "
                f"{r:.2f} over {len(a)} positions, p = {p:.2g}): a rigid turn tilts both")  # fmt: skip
    return ""


def estimate_large_misalignment(fit: SessionFit, half) -> Estimate:
    """Misalignment angle |alpha| (deg) of each sensor of the fitted calibration (exact
    rotation); detection: the largest."""
    params = {
        f"{s}_deg": float(np.degrees(np.linalg.norm(
            errormodel.decompose(fit.calibration.sensor(s).matrix).alpha_rad)))
        for s in SENSORS
    }  # fmt: skip
    return Estimate(params, max(params.values()))


_NOT_FITTED = "no rotation: the alignment T_R is not fitted on a static recording"
_ONE_POSE = "one pose: a tilt from a nominal direction needs a second pose"
_MEASURED = "the mounting against the reference is measured per recording"

# random tilts of each placement, drawn afresh in every replica: they widen the null of the
# direction residuals rather than move the mean of a statistic
PLACEMENT_ERROR = register(EffectSpec(
    name="placement_error",
    description="the cube, V-block and rate-table mountings off their nominal orientations",
    kind="spread",
    scopes={
        "protocol": EffectModel("placement_error", estimate_placement_error,
                                (("acc_cube", "acc", "dir_resid_rad"),),
                                "cube / table poses tilted from their nominal directions while "
                                "|a| fits", gate=placement_gate),
        "static": _ONE_POSE,
        "motion": _MEASURED,
        "rests": "each rest is replayed at its own level: the rests' means are not compared "
        "with each other",
        "field_fit": _ONE_POSE,
    },
))  # fmt: skip

LARGE_MISALIGNMENT = register(EffectSpec(
    name="large_misalignment",
    description="misalignment rotations T_R of several degrees, where the small-angle form fails",
    kind="systematic",
    scopes={
        "protocol": EffectModel("large_misalignment", estimate_large_misalignment, (),
                                "misalignment of several degrees: absorbed by the exact "
                                "rotation, a gap only with the small-angle variant",
                                opens_gap=False),
        "static": _NOT_FITTED,
        "motion": _MEASURED,
        "rests": _NOT_FITTED,
        "field_fit": _NOT_FITTED,
    },
))  # fmt: skip
