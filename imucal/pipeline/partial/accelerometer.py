"""The accelerometer runners of the partial path: known orientations (Ferraris), the cube fit on
many static poses, ``T_R,acc`` on the rotation3d phases and the gravity direction of an
orientation reference. Each raises :class:`~imucal.pipeline.partial.session.NotApplicable` with
the reason when the session does not allow it.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from imucal.calibration import SensorCalibration
from imucal.columns import ACC
from imucal.pipeline import stages
from imucal.pipeline.partial.session import Session, axis_vector, need
from imucal.pipeline.registry import FINAL
from imucal.segments.table import cut_finite


def acc_known_orientation(s: Session, done: Mapping[str, dict]) -> dict:
    from imucal.fits import ferraris

    need(s.with_sensor("ferraris", "acc"), "needs a ferraris recording with accelerometer data")
    rows = s.poses("ferraris")
    need("up" in rows.columns, "the ferraris segments carry no 'up' direction")
    rows = rows[rows["up"].notna() & (rows["up"].astype(str) != "")]
    need(len(rows) >= 4, f"{len(rows)} static faces with a known up direction, expected >= 4")
    positions = [v for _, v in cut_finite(s.tables["ferraris"], rows, ACC)]
    directions = np.array([axis_vector(str(u)) for u in rows["up"]])
    fit = ferraris.fit_known_orientations(
        positions, directions, s.gravity_m_s2, labels=[str(x) for x in rows["label"]]
    )
    artifact = stages.plain(fit)
    artifact.update(calibration=fit.calibration.to_dict(), gravity_m_s2=s.gravity_m_s2)
    if len(positions) >= ferraris.MIN_POSITIONS + 2:
        held = ferraris.heldout_positions(positions, directions, s.gravity_m_s2)
        artifact.update(heldout_error_m_s2=held.errors_m_s2.tolist(), heldout_z2=held.z2.tolist())
    return artifact


def acc_cube(s: Session, done: Mapping[str, dict]) -> dict:
    return s.run_node("acc_cube", **s.tables, segments=s.segments)


def acc_align(s: Session, done: Mapping[str, dict]) -> dict:
    need("acc_cube" in done, "needs the cube fit (acc_cube)")
    s.need_phases("acc")
    return s.run_node(
        "acc_align", lowpass=s.rotation3d_lowpass, segments=s.segments, acc_cube=done["acc_cube"]
    )


def acc_reference(s: Session, done: Mapping[str, dict]) -> dict:
    from imucal.pipeline.reference import fit_acc_reference

    need("gyr_reference" in done, "needs the gyroscope against the reference (gyr_reference)")
    return fit_acc_reference(
        s.tables, s.references, s.segments, done["gyr_reference"], s.gravity_m_s2
    )


def acc_final(done: Mapping[str, dict]) -> SensorCalibration | None:
    """The accelerometer's calibration of the first of its final stages that ran, else None."""
    for stage in FINAL["acc"]:
        if stage in done:
            return SensorCalibration.from_dict("acc", done[stage]["calibration"])
    return None
