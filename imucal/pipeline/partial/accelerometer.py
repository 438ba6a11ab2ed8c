"""The accelerometer runners of the partial path: known orientations (Ferraris), the cube fit on
many static poses, ``T_R,acc`` on the rotation3d phases and the gravity direction of an
orientation reference. Each raises :class:`~imucal.pipeline.partial.session.NotApplicable` with
the reason when the session does not allow it.
"""

from __future__ import annotations

import numpy as np

from imucal.calibration import SensorCalibration
from imucal.columns import ACC
from imucal.pipeline import stages
from imucal.pipeline.partial.session import _axis_vector, _need, _Session
from imucal.pipeline.registry import FINAL
from imucal.segments.table import cut_finite


def _acc_known_orientation(s: _Session) -> dict:
    from imucal.fits import ferraris

    _need(s.with_sensor("ferraris", "acc"), "needs a ferraris recording with accelerometer data")
    rows = s.poses("ferraris")
    _need("up" in rows.columns, "the ferraris segments carry no 'up' direction")
    rows = rows[rows["up"].notna() & (rows["up"].astype(str) != "")]
    _need(len(rows) >= 4, f"{len(rows)} static faces with a known up direction, expected >= 4")
    positions = [v for _, v in cut_finite(s.tables["ferraris"], rows, ACC)]
    directions = np.array([_axis_vector(str(u)) for u in rows["up"]])
    fit = ferraris.fit_known_orientations(
        positions, directions, s.gravity_m_s2, labels=[str(x) for x in rows["label"]]
    )
    artifact = stages.plain(fit)
    artifact.update(calibration=fit.calibration.to_dict(), gravity_m_s2=s.gravity_m_s2)
    if len(positions) >= ferraris.MIN_POSITIONS + 2:
        held = ferraris.heldout_positions(positions, directions, s.gravity_m_s2)
        artifact.update(heldout_error_m_s2=held.errors_m_s2.tolist(), heldout_z2=held.z2.tolist())
    return artifact


def _acc_cube(s: _Session) -> dict:
    return s.run_node("acc_cube", **s.tables, segments=s.segments)


def _acc_align(s: _Session) -> dict:
    _need("acc_cube" in s.done, "needs the cube fit (acc_cube)")
    s.need_phases("acc")
    return s.run_node(
        "acc_align", lowpass=s.rotation3d_lowpass, segments=s.segments, acc_cube=s.done["acc_cube"]
    )


def _acc_reference(s: _Session) -> dict:
    from imucal.pipeline.reference import fit_acc_reference

    _need("gyr_reference" in s.done, "needs the gyroscope against the reference (gyr_reference)")
    return fit_acc_reference(
        s.tables, s.references, s.segments, s.done["gyr_reference"], s.gravity_m_s2
    )


def _acc_final(s: _Session) -> SensorCalibration | None:
    for stage in FINAL["acc"]:
        if stage in s.done:
            return SensorCalibration.from_dict("acc", s.done[stage]["calibration"])
    return None
