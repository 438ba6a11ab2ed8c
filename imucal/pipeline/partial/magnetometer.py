"""The magnetometer runners of the partial path: step 1 (ellipsoid fit) on the recordings that
turn the module, step 2 (``T_R,mag``) on the rotation3d phases, and the fit against an
orientation reference. Each raises :class:`~imucal.pipeline.partial.session.NotApplicable` with
the reason when the session does not allow it.
"""

from __future__ import annotations

from imucal.pipeline.partial.session import _need, _Session

#: Recordings whose magnetometer samples may feed the ellipsoid fit, preferred first.
MAG_RECORDINGS = ("tumble", "rotation3d", "cube", "poses", "ferraris", "static")


#: Recordings held at one orientation: they add one direction to the ellipsoid, and their
#: thousands of samples there would outweigh the turning recordings with an error that does not
#: average out over them (the reading's quantisation at a fixed field, a local field); offered
#: to the fit only when they are the only source (which the coverage check then refuses).
ONE_ORIENTATION = ("static",)


def _mag_step1(s: _Session) -> dict:
    from imucal.fits import magnetometer

    sources = [r for r in MAG_RECORDINGS if s.with_sensor(r, "mag")]
    _need(bool(sources), "no recording has magnetometer samples")
    primary, extra = sources[0], [r for r in sources[1:] if r not in ONE_ORIENTATION]
    _, samples = magnetometer.field_samples(s.tables[primary])
    fit = magnetometer.fit_ellipsoid(
        samples,
        refine_lm=s.methods.mag_refine_lm,
        field_norm=s.field_norm,
        extra_samples={r: magnetometer.field_samples(s.tables[r])[1] for r in extra} or None,
    )
    return {**fit.to_dict(), "source": primary, "offered": extra}


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
