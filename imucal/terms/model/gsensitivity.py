"""The gyroscope's g-sensitivity: ``w_B = v_gyr - G a_B``.

``a_B`` is the calibrated specific force of the same sample (``G`` in rad/s per m/s^2, frame
B). Kalibr and OpenVINS carry it (their ``A`` and ``Tg``). The estimator is
:func:`imucal.terms.gsensitivity.fit_g_sensitivity`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from imucal.terms.term import ModelTerm, ReportRow, Samples


@dataclass(frozen=True)
class GSensitivity(ModelTerm):
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

    matrix: np.ndarray
    std: np.ndarray
    method: str = ""

    def __post_init__(self) -> None:
        for name in ("matrix", "std"):
            m = np.asarray(getattr(self, name), dtype=float)
            if m.shape != (3, 3) or not np.all(np.isfinite(m)):
                raise ValueError(f"g_sensitivity.{name} must be a finite 3x3 matrix, got {m!r}")
            object.__setattr__(self, name, m)

    @classmethod
    def estimate(cls, fit: Any, settings: Any) -> tuple[GSensitivity | None, dict]:
        from imucal.terms.gsensitivity import fit_g_sensitivity

        return fit_g_sensitivity(fit)

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

    def to_dict(self) -> dict:
        return {
            "matrix": self.matrix.tolist(),
            "std": self.std.tolist(),
            "unit": "rad/s per m/s^2 (frame B; row: gyro axis, column: specific-force axis)",
            "method": self.method,
        }

    @classmethod
    def from_dict(cls, d: Mapping) -> GSensitivity:
        if "matrix" not in d:
            raise ValueError("g_sensitivity term lacks the key 'matrix'")
        return cls(d["matrix"], d.get("std", np.zeros((3, 3))), d.get("method", ""))

    def report_rows(self) -> list[ReportRow]:
        d = self.to_dict()
        return [ReportRow("g-sensitivity G", d["matrix"], d["std"], d["unit"])]
