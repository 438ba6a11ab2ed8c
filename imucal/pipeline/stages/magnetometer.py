"""The magnetometer stages: step 1 (the ellipsoid fit) and step 2 (the alignment with the
accelerometer).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd

from imucal.pipeline.stages.common import _phases
from imucal.validation.plausibility import bound_warnings


def fit_mag_step1(
    rotation3d: pd.DataFrame,
    cube: pd.DataFrame | None = None,
    *,
    field_norm: float = 1.0,
    refine_lm: bool = True,
) -> dict:
    """Magnetometer step 1 (eqs. 17-24): ellipsoid fit to the rotation3d magnetometer samples.

    The cube's samples, when given, are offered for coverage and join only if they were
    recorded in the same field (see :func:`imucal.fits.magnetometer.fit_ellipsoid`).
    """
    from imucal.fits import magnetometer

    _, samples = magnetometer.field_samples(rotation3d)
    extra = None if cube is None else {"cube": magnetometer.field_samples(cube)[1]}
    fit = magnetometer.fit_ellipsoid(
        samples, refine_lm=refine_lm, field_norm=field_norm, extra_samples=extra
    )
    return fit.to_dict()


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
        for label, values in _phases(rotation3d, segments, "mag").items()
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
