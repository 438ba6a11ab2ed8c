"""The magnetometer runners of the partial path: step 1 (ellipsoid fit) on the recordings that
turn the module, step 2 (``T_R,mag``) on the rotation3d phases, and the fit against an
orientation reference. Each raises :class:`~imucal.pipeline.partial.session.NotApplicable` with
the reason when the session does not allow it.
"""

from __future__ import annotations

from collections.abc import Mapping

from imucal.pipeline.partial.session import Session, need


def mag_step1(s: Session, done: Mapping[str, dict]) -> dict:
    return s.run_node("mag_step1", **s.tables)


def mag_step2(s: Session, done: Mapping[str, dict]) -> dict:
    need("mag_step1" in done, "needs the ellipsoid fit (mag_step1)")
    s.need_phases("mag")
    return s.run_node(
        "mag_step2",
        rotation3d=s.tables["rotation3d"],
        segments=s.segments,
        mag_step1=done["mag_step1"],
    )


def mag_reference(s: Session, done: Mapping[str, dict]) -> dict:
    from imucal.pipeline.reference import fit_mag_reference

    need("mag_step1" in done, "needs the ellipsoid fit (mag_step1)")
    need("gyr_reference" in done, "needs the gyroscope against the reference (gyr_reference)")
    return fit_mag_reference(s.tables, s.references, done["mag_step1"], done["gyr_reference"])
