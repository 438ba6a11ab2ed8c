"""The closed loop: optional model terms estimated where the gap diagnosis accepts their effect.

Temperature polynomials (:mod:`.temperature`), the gyroscope's g-sensitivity
(:mod:`.gsensitivity`), the accelerometer's lever arm on the rate table (:mod:`.leverarm`), the
magnetometer's delay (:mod:`.magdelay`), the switch per term
(:mod:`.selection`) and the loop that folds them into the calibration (:mod:`.loop`). The
terms themselves (data, units, evaluation) are :mod:`imucal.modelterms`.
"""

from imucal.terms.gsensitivity import fit_g_sensitivity
from imucal.terms.leverarm import fit_lever_arm
from imucal.terms.loop import (
    close_loop,
    corrected_session,
    diagnosis_after,
    final_calibration,
    terms_summary,
)
from imucal.terms.magdelay import fit_mag_delay
from imucal.terms.selection import EFFECT_OF_TERM, TermSettings, decide
from imucal.terms.temperature import fit_temperature, select_model

__all__ = [
    "EFFECT_OF_TERM",
    "TermSettings",
    "close_loop",
    "corrected_session",
    "decide",
    "diagnosis_after",
    "final_calibration",
    "fit_g_sensitivity",
    "fit_lever_arm",
    "fit_mag_delay",
    "fit_temperature",
    "select_model",
    "terms_summary",
]
