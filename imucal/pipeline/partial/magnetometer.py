"""The magnetometer runners of the partial path: step 1 (ellipsoid fit) on the recordings that
turn the module, step 2 (``T_R,mag``) on the rotation3d phases, and the fit against an
orientation reference. Each raises :class:`~imucal.pipeline.partial.session.NotApplicable` with
the reason when the session does not allow it.
"""

from __future__ import annotations

from imucal.pipeline.partial.session import _need, _Session


def _mag_step1(s: _Session) -> dict:
    return s.run_node("mag_step1", **s.tables)


def _mag_step2(s: _Session) -> dict:
    _need("mag_step1" in s.done, "needs the ellipsoid fit (mag_step1)")
    s.need_phases("mag")
    return s.run_node(
        "mag_step2",
        rotation3d=s.tables["rotation3d"],
        segments=s.segments,
        mag_step1=s.done["mag_step1"],
    )


def _mag_reference(s: _Session) -> dict:
    from imucal.pipeline.reference import fit_mag_reference

    _need("mag_step1" in s.done, "needs the ellipsoid fit (mag_step1)")
    _need("gyr_reference" in s.done, "needs the gyroscope against the reference (gyr_reference)")
    return fit_mag_reference(s.tables, s.references, s.done["mag_step1"], s.done["gyr_reference"])
