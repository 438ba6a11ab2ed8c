"""The magnetometer's delay against acc/gyro: ``m_B = v_mag - delay (w_B x v_mag)``.

The first-order advance of a field that turns in B at ``-w_B`` by the delay (s), with ``w_B``
the calibrated rate of the same sample. The estimator is
:func:`imucal.terms.magdelay.fit_mag_delay`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from imucal.modelterms.contract import Samples, ValueTerm


@dataclass(frozen=True)
class MagDelay(ValueTerm):
    """Delay of the magnetometer behind acc/gyro (s): its reading is the field of
    ``delay_s`` earlier (mean age of a held sample included).

    Attributes
    ----------
    delay_s : float
    std_s : float
    method : str
    """

    name = "mag_delay"
    effect = "mag_latency"
    value_field, std_field, value_shape = "delay_s", "std_s", ()
    unit = "s"
    report_label = "magnetometer delay"
    switch_description = "magnetometer delay behind acc/gyro (s)"

    delay_s: float
    std_s: float
    method: str = ""

    def correct(self, values: Mapping[str, np.ndarray], samples: Samples) -> dict:
        """Takes ``delay (w_B x m_B)`` from the calibrated field."""
        return {
            **values,
            "mag": values["mag"] - self.delay_s * np.cross(values["gyr"], values["mag"]),
        }

    def variance(
        self,
        values: Mapping[str, np.ndarray],
        brackets: Mapping[str, np.ndarray],
        samples: Samples,
    ) -> dict:
        return {"mag": (self.std_s * np.cross(values["gyr"], values["mag"])) ** 2}
