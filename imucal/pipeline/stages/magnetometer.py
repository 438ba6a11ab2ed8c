"""The magnetometer stages: step 1 (the ellipsoid fit) and step 2 (the alignment with the
accelerometer).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd

from imucal.pipeline.outcome import NotApplicable
from imucal.pipeline.stages.common import phase_values, sensors_of
from imucal.validation.plausibility import bound_warnings

#: Recordings whose magnetometer samples may feed the ellipsoid fit, preferred first.
MAG_RECORDINGS = ("tumble", "rotation3d", "cube", "poses", "ferraris", "static")
#: Recordings held at one orientation: they add one direction to the ellipsoid, and their
#: thousands of samples there would outweigh the turning recordings with an error that does not
#: average out over them (the reading's quantisation at a fixed field, a local field); offered
#: to the fit only when they are the only source (which the coverage check then refuses).
ONE_ORIENTATION = ("static",)


def fit_mag_step1(
    tables: Mapping[str, pd.DataFrame], *, field_norm: float = 1.0, refine_lm: bool = True
) -> dict:
    """Magnetometer step 1 (eqs. 17-24): the ellipsoid fit to the samples of the recordings
    that turn the module.

    The first of :data:`MAG_RECORDINGS` with magnetometer samples is fitted; the others are
    offered for coverage and join only if they were recorded in the same field (see
    :func:`imucal.fits.magnetometer.fit_ellipsoid`); a recording held at one orientation
    (:data:`ONE_ORIENTATION`) is not offered.

    Parameters
    ----------
    tables : dict of str to DataFrame
        Ingested recordings by name (T); the paper's protocol gives rotation3d and the cube.
    field_norm : float
        Norm of the calibrated field (1 for a unit sphere).
    refine_lm : bool
        Levenberg-Marquardt refinement after the SVD fit.

    Returns
    -------
    dict
        ``EllipsoidFit.to_dict()`` with ``source`` (the fitted recording) and ``offered``.

    Raises
    ------
    NotApplicable
        If no recording has magnetometer samples.
    """
    from imucal.fits import magnetometer

    sources = [r for r in MAG_RECORDINGS if r in tables and "mag" in sensors_of(tables[r])]
    if not sources:
        raise NotApplicable("no recording has magnetometer samples")
    primary, extra = sources[0], [r for r in sources[1:] if r not in ONE_ORIENTATION]
    _, samples = magnetometer.field_samples(tables[primary])
    fit = magnetometer.fit_ellipsoid(
        samples,
        refine_lm=refine_lm,
        field_norm=field_norm,
        extra_samples={r: magnetometer.field_samples(tables[r])[1] for r in extra} or None,
    )
    return {**fit.to_dict(), "source": primary, "offered": extra}


def align_mag(
    rotation3d: pd.DataFrame,
    segments: pd.DataFrame,
    step1: Mapping,
    *,
    method: str = "full",
    exact: bool = True,
    with_covariance: bool = True,
) -> dict:
    """Magnetometer step 2 (eqs. 25-27): ``T_R,mag`` from the rotation3d phases, both methods;
    ``with_covariance`` as :func:`imucal.fits.magnetometer.calibrate_alignment`."""
    from imucal.fits import magnetometer

    fit = magnetometer.EllipsoidFit.from_dict(dict(step1))
    phases = {
        label: values[np.all(np.isfinite(values), axis=1)]
        for label, values in phase_values(rotation3d, segments, "mag").items()
    }
    result = magnetometer.calibrate_alignment(
        fit, phases, method=method, exact=exact, with_covariance=with_covariance
    )
    artifact = result.to_dict()
    artifact["warnings"] = [
        *step1.get("warnings", []),
        *bound_warnings("mag_step2", "mag", artifact["calibration"]),
    ]
    return artifact
