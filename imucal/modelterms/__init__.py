"""Optional terms of the calibration model beyond the paper's bias and matrix.

The paper's model is ``calibrated = K (reading - o)`` (eq. 11). A calibration may add terms the
gap diagnosis has shown a session needs (``docs/model-terms.md``); with all of them the
calibrated values of one sample are

1. temperature (per sensor, per axis): ``v = K (reading - o - b(dT)) / (1 + s(dT))``
   elementwise inside the bracket, with ``dT = T - reference_c`` and the polynomials
   ``b(dT) = sum_k bias[k-1] dT^k``, ``s(dT) = sum_k scale[k-1] dT^k`` (k = 1 .. order; the
   constant term is the paper's bias and matrix, which hold at ``reference_c``);
2. g-sensitivity of the gyroscope: ``w_B = v_gyr - G a_B`` with ``a_B`` the calibrated
   specific force of the same sample (``G`` in rad/s per m/s^2, frame B);
3. lever arm of the accelerometer from the rotation centre of the rate table:
   ``a_B = v_acc - w_B x (w_B x r) - dw_B/dt x r`` (``r`` in m, frame B; ``w_B`` the gyroscope's
   calibrated rate of the same sample, its derivative over :data:`LEVER_ARM_DIFF_S`);
4. magnetometer delay against acc/gyro: ``m_B = v_mag - delay (w_B x v_mag)``, the first-order
   advance of a field that turns in B at ``-w_B`` by the delay (s).

Each term is one module of this package keeping the contract of
:class:`~imucal.modelterms.contract.ModelTerm` (its correction, variance, dict form, report rows,
export note and config settings), registered in :mod:`.registry`, whose order is the order
above; :mod:`.collection` holds :class:`ModelTerms`, the terms of one calibration. The package
is part of the model at the bottom of the layers: it imports nothing above
:mod:`imucal.columns`. The terms' estimators need a fitted session and live above the diagnosis
(:mod:`imucal.terms.estimators`, found by the term's name).
"""

from imucal.modelterms.collection import ModelTerms
from imucal.modelterms.contract import SAMPLE_INPUTS, ModelTerm, ReportRow, Samples, ValueTerm
from imucal.modelterms.gsensitivity import GSensitivity
from imucal.modelterms.leverarm import LEVER_ARM_DIFF_S, LeverArm, angular_acceleration
from imucal.modelterms.magdelay import MagDelay
from imucal.modelterms.registry import (
    declaration_problems,
    register,
    registered_terms,
    settings_schema,
    term_class,
    term_names,
    unregister,
)
from imucal.modelterms.temperature import (
    TEMPERATURE_SENSORS,
    TemperaturePolynomial,
    TemperatureTerm,
)

__all__ = [
    "LEVER_ARM_DIFF_S",
    "SAMPLE_INPUTS",
    "TEMPERATURE_SENSORS",
    "GSensitivity",
    "LeverArm",
    "MagDelay",
    "ModelTerm",
    "ModelTerms",
    "ReportRow",
    "Samples",
    "TemperaturePolynomial",
    "TemperatureTerm",
    "ValueTerm",
    "angular_acceleration",
    "declaration_problems",
    "register",
    "registered_terms",
    "settings_schema",
    "term_class",
    "term_names",
    "unregister",
]
