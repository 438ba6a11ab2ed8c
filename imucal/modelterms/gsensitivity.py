"""The gyroscope's g-sensitivity: ``w_B = v_gyr - G a_B``.

``a_B`` is the calibrated specific force of the same sample (``G`` in rad/s per m/s^2, frame
B). Kalibr and OpenVINS carry it (their ``A`` and ``Tg``). The estimator is
:func:`imucal.terms.gsensitivity.fit_g_sensitivity`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from imucal.modelterms.contract import Samples, ValueTerm


@dataclass(frozen=True)
class GSensitivity(ValueTerm):
    """Gyroscope output per specific force, in frame B: ``w_B -= matrix @ a_B``.

    Attributes
    ----------
    matrix : ndarray, shape (3, 3)
        rad/s per m/s^2; row: gyro axis of B, column: specific-force axis of B.
    std : ndarray, shape (3, 3)
    method : str
    """

    name = "g_sensitivity"
    effect = "g_sensitivity"
    exported_by = frozenset({"kalibr", "openvins"})
    heldout_residual = "resting calibrated gyro means, each predicted from the others (rad/s)"
    value_field, std_field, value_shape = "matrix", "std", (3, 3)
    unit = "rad/s per m/s^2 (frame B; row: gyro axis, column: specific-force axis)"
    report_label = "g-sensitivity G"
    switch_description = "gyroscope g-sensitivity matrix (rad/s per m/s^2)"

    matrix: np.ndarray
    std: np.ndarray
    method: str = ""

    def correct(self, values: Mapping[str, np.ndarray], samples: Samples) -> dict:
        return {**values, "gyr": values["gyr"] - values["acc"] @ self.matrix.T}

    def variance(
        self,
        values: Mapping[str, np.ndarray],
        brackets: Mapping[str, np.ndarray],
        samples: Samples,
    ) -> dict:
        """Variance of ``matrix @ a_B`` from the entries' standard deviations (first order,
        independent) for the specific force of ``values``."""
        return {"gyr": np.asarray(values["acc"]) ** 2 @ (self.std**2).T}
