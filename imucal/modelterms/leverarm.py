"""The accelerometer's lever arm from the rate table's rotation centre.

``a_B = v_acc - w_B x (w_B x r) - dw_B/dt x r`` (``r`` in m, frame B; ``w_B`` the gyroscope's
calibrated rate of the same sample, its derivative over :data:`LEVER_ARM_DIFF_S`). The
estimator is :func:`imucal.terms.leverarm.fit_lever_arm`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from imucal.modelterms.contract import Samples, ValueTerm

#: Time (s) over which the lever arm's angular acceleration is taken (central difference of the
#: rate ``LEVER_ARM_DIFF_S`` apart): long enough that the gyroscope's white noise, divided by it,
#: adds less to the tangential term than the accelerometer's own noise (0.002 rad/s over 0.1 s
#: at r = 5 cm is 1e-3 m/s^2), short against a rate table's spin-up (about 1 s).
LEVER_ARM_DIFF_S = 0.1


def angular_acceleration(t_s: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """Derivative of the rate, central difference over :data:`LEVER_ARM_DIFF_S`.

    Parameters
    ----------
    t_s : ndarray, shape (n,)
        Sample times (s), increasing.
    omega : ndarray, shape (n, 3)
        Rate (rad/s), finite.

    Returns
    -------
    ndarray, shape (n, 3)
        rad/s^2; at the ends the difference is one-sided over what the recording has.
    """
    h = 0.5 * LEVER_ARM_DIFF_S
    lo = np.clip(t_s - h, t_s[0], t_s[-1])
    hi = np.clip(t_s + h, t_s[0], t_s[-1])
    span = np.where(hi > lo, hi - lo, np.inf)
    ahead = np.column_stack([np.interp(hi, t_s, omega[:, j]) for j in range(3)])
    behind = np.column_stack([np.interp(lo, t_s, omega[:, j]) for j in range(3)])
    return (ahead - behind) / span[:, None]


def rate_per_sample(
    t_s: np.ndarray | None, omega: np.ndarray, source: str
) -> tuple[np.ndarray, np.ndarray]:
    """Times and the calibrated rate at every sample for the lever arm (rows without a gyro
    reading interpolated in time from their neighbours).

    Raises
    ------
    ValueError
        Without ``t_s``, with times not finite and increasing per sample, or with fewer than
        two gyroscope readings.
    """
    if t_s is None:
        raise ValueError(
            f"{source}: the calibration has a lever arm; its tangential term needs the sample "
            "times (t_s), none were given"
        )
    t = np.asarray(t_s, dtype=float)
    ok = np.all(np.isfinite(omega), axis=1)
    if t.shape != (len(omega),) or not np.all(np.isfinite(t)) or np.any(np.diff(t) < 0):
        raise ValueError(
            f"{source}: the lever arm needs a finite, increasing time per sample "
            f"({len(omega)}), got shape {t.shape}"
        )
    if ok.sum() < 2:
        raise ValueError(
            f"{source}: the calibration has a lever arm, which needs the gyroscope's rate in "
            f"the same recording; {int(ok.sum())} of {len(omega)} samples have a gyro reading"
        )
    if ok.all():
        return t, omega
    return t, np.column_stack([np.interp(t, t[ok], omega[ok, j]) for j in range(3)])


@dataclass(frozen=True)
class LeverArm(ValueTerm):
    """Position of the accelerometer relative to the rate table's rotation centre, in B.

    The accelerometer senses ``w x (w x r) + dw/dt x r`` on top of the specific force at the
    centre; the term removes it with the gyroscope's rate of the same sample.

    Attributes
    ----------
    r_m : ndarray, shape (3,)
        Lever arm (m), frame B.
    std_m : ndarray, shape (3,)
        Standard deviations (m).
    method : str
    """

    name = "lever_arm"
    effect = "lever_arm"
    needs = frozenset({"t_s"})  # the tangential term differentiates the rate in time
    heldout_residual = (
        "rate-table run means of the acc at half the rate levels, predicted from the other "
        "half (m/s^2)"
    )
    value_field, std_field, value_shape = "r_m", "std_m", (3,)
    unit = "m (frame B; accelerometer relative to the rate table's rotation centre)"
    report_label = "lever arm r"
    switch_description = (
        "lever arm of the accelerometer from the rate table's rotation centre (m, frame B)"
    )

    r_m: np.ndarray
    std_m: np.ndarray
    method: str = ""

    @staticmethod
    def _sensed(omega: np.ndarray, w_dot: np.ndarray, r: np.ndarray) -> np.ndarray:
        """``w x (w x r) + dw/dt x r`` (n, 3): linear in ``r``."""
        return np.cross(omega, np.cross(omega, r)) + np.cross(w_dot, r)

    def acceleration(self, t_s: np.ndarray, omega: np.ndarray) -> np.ndarray:
        """``w x (w x r) + dw/dt x r`` (m/s^2, shape (n, 3)) for rates ``omega`` (rad/s, frame
        B, shape (n, 3), finite) at times ``t_s`` (s, shape (n,))."""
        return self._sensed(omega, angular_acceleration(t_s, omega), self.r_m)

    def correct(self, values: Mapping[str, np.ndarray], samples: Samples) -> dict:
        """Takes :meth:`acceleration` at the calibrated rate from the specific force.

        Raises
        ------
        ValueError
            Without sample times or without a gyroscope reading (:func:`rate_per_sample`).
        """
        rate = rate_per_sample(samples.t_s, values["gyr"], samples.source)
        return {**values, "acc": values["acc"] - self.acceleration(*rate)}

    def variance(
        self,
        values: Mapping[str, np.ndarray],
        brackets: Mapping[str, np.ndarray],
        samples: Samples,
    ) -> dict:
        """Variance of :meth:`acceleration` from ``std_m`` (independent axes): it is linear in
        ``r``, its column j that of ``e_j``."""
        t_s, omega = rate_per_sample(samples.t_s, values["gyr"], samples.source)
        w_dot = angular_acceleration(t_s, omega)
        return {"acc": sum((self._sensed(omega, w_dot, e) * sd) ** 2
                           for e, sd in zip(np.eye(3), self.std_m, strict=True))}  # fmt: skip
