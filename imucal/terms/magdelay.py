"""The magnetometer's delay behind acc/gyro from the platform's rotation phases."""

from __future__ import annotations

import numpy as np

from imucal.columns import AXES
from imucal.gap import session as st
from imucal.modelterms.magdelay import MagDelay
from imucal.pipeline.full import SessionFit


def fit_mag_delay(fit: SessionFit) -> tuple[MagDelay | None, dict]:
    """Lag of the calibrated field behind the integrated rate, combined over the three phases.

    Each phase gives a lag and its least-squares standard deviation
    (:func:`imucal.gap.session.magnetometer_lag_fit`); the term is their inverse-variance
    weighted mean. Its standard deviation is that of the weighted mean, widened by the Birge
    ratio ``sqrt(chi2 / (n - 1))`` when the phases disagree by more than their own standard
    deviations allow (three phases alone are too few for a spread-based standard deviation:
    with two degrees of freedom it is itself uncertain by a factor of two).

    The delay is the mean age of the field values the recording carries: with a held output
    (a magnetometer on its own clock, read at the packet rate) it is the conversion delay
    plus the mean time since the held sample was taken, over the rows that carry a field.

    Returns
    -------
    term : MagDelay or None
        None with fewer than two phases.
    evidence : dict
        ``lags_s`` and ``lag_std_s`` per phase, ``birge_ratio``, or ``refused``.
    """
    found = {a: st.magnetometer_lag_fit(fit, a) for a in AXES}
    ok = {a: v for a, v in found.items() if np.isfinite(v[0]) and v[1] > 0}
    if len(ok) < 2:
        return None, {"refused": "fewer than two rotation phases to measure the lag in"}
    lag = np.array([v[0] for v in ok.values()])
    weight = 1.0 / np.array([v[1] for v in ok.values()]) ** 2
    mean = float(np.sum(weight * lag) / np.sum(weight))
    chi2 = float(np.sum(weight * (lag - mean) ** 2))
    birge = max(1.0, float(np.sqrt(chi2 / (len(lag) - 1))))
    std = birge / float(np.sqrt(np.sum(weight)))
    method = (
        "lag of the field's angle behind the integrated rate per phase, inverse-variance "
        "weighted mean (std widened by the Birge ratio when the phases disagree)"
    )
    evidence = {
        "lags_s": {a: v[0] for a, v in found.items()},
        "lag_std_s": {a: v[1] for a, v in found.items()},
        "birge_ratio": birge,
        "unit": "s",
    }
    return MagDelay(mean, std, method), evidence
