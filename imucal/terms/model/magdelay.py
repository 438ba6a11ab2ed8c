"""The magnetometer's delay against acc/gyro: ``m_B = v_mag - delay (w_B x v_mag)``.

The first-order advance of a field that turns in B at ``-w_B`` by the delay (s), with ``w_B``
the calibrated rate of the same sample. The estimator is
:func:`imucal.terms.magdelay.fit_mag_delay`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from imucal.terms.term import ModelTerm, ReportRow, Samples


@dataclass(frozen=True)
class MagDelay(ModelTerm):
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

    delay_s: float
    std_s: float
    method: str = ""

    def __post_init__(self) -> None:
        for name in ("delay_s", "std_s"):
            v = float(getattr(self, name))
            if not np.isfinite(v):
                raise ValueError(f"mag_delay.{name} must be finite, got {v}")
            object.__setattr__(self, name, v)

    @classmethod
    def estimate(cls, fit: Any, settings: Any) -> tuple[MagDelay | None, dict]:
        from imucal.terms.magdelay import fit_mag_delay

        return fit_mag_delay(fit)

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

    def to_dict(self) -> dict:
        return {"delay_s": self.delay_s, "std_s": self.std_s, "unit": "s", "method": self.method}

    @classmethod
    def from_dict(cls, d: Mapping) -> MagDelay:
        if "delay_s" not in d:
            raise ValueError("mag_delay term lacks the key 'delay_s'")
        return cls(d["delay_s"], d.get("std_s", 0.0), d.get("method", ""))

    def report_rows(self) -> list[ReportRow]:
        return [ReportRow("magnetometer delay", self.delay_s, self.std_s, "s")]
