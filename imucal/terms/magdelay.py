"""The magnetometer's delay behind acc/gyro from the platform's rotation phases."""

from __future__ import annotations

import numpy as np

from imucal.columns import AXES
from imucal.gap import statistics as st
from imucal.modelterms import MagDelay
from imucal.pipeline.full import SessionFit


def fit_mag_delay(fit: SessionFit) -> tuple[MagDelay | None, dict]:
    """Mean lag of the calibrated field behind the integrated rate over the three phases
    (:func:`imucal.gap.statistics.magnetometer_lag`); standard deviation: their spread over
    the root of their number.

    Returns
    -------
    term : MagDelay or None
        None with fewer than two phases.
    evidence : dict
        ``lags_s`` per phase, or ``refused``.
    """
    lags = {a: st.magnetometer_lag(fit, a) for a in AXES}
    found = np.array([v for v in lags.values() if np.isfinite(v)])
    if len(found) < 2:
        return None, {"refused": "fewer than two rotation phases to measure the lag in"}
    std = float(np.std(found, ddof=1) / np.sqrt(len(found)))
    method = "lag of the field's angle behind the integrated rate, mean over the phases"
    return MagDelay(float(found.mean()), std, method), {"lags_s": lags, "unit": "s"}
