"""The reference device: a factory-calibrated Xsens MTx riding on the platform during rotation3d.

Its axes differ from B by a small mounting rotation, its clock is its own, its readings carry
white noise only (no calibration error, no packet loss). It is written as an MT Manager ASCII
export (``//`` header lines, tab-separated table).

Clock convention
----------------
``tau = (t_module + offset_s) * (1 + drift_ppm * 1e-6)``, where ``tau`` is the reference time of
a sample since the reference's first sample (``(SampleTimeFine - SampleTimeFine[0]) / 10000``)
and ``t_module`` the module time of the rotation3d recording (its ``t_s`` axis, sample ``k`` at
``k / 100`` s). A positive offset means the reference started ``offset_s`` before the module, so
every event appears ``offset_s`` later on the reference's time axis.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation

from imucal.columns import (
    REF_ACC,
    REF_COUNTER,
    REF_GYR,
    REF_MAG,
    REF_TICKS_PER_S,
    REF_TIME_FINE,
    SENSORS,
    SEQ_MODULUS,
)
from imucal.sim.motion import Motion, evaluate_motion
from imucal.sim.sensors import true_signals
from imucal.sim.truth import World

#: Header lines of the export, as MT Manager writes them (the update rate line is parsed).
_HEADER = (
    "// Start Time: 2013-11-04 10:21:33.000",
    "// Update Rate: {rate:.1f}Hz",
    "// Filter Profile: human (46.1)",
    "// Option Flags: AHS Disabled, ICW Disabled",
    "// Firmware Version: 2.5.1",
    "// Device ID: 00300123",
)
_REF_COLUMNS = {"acc": REF_ACC, "gyr": REF_GYR, "mag": REF_MAG}


@dataclass(frozen=True)
class ReferenceClock:
    """Offset (s) and drift (ppm) of the reference clock; see the module docstring."""

    offset_s: float = 0.0
    drift_ppm: float = 0.0

    def module_time(self, tau_s: np.ndarray) -> np.ndarray:
        """Module time (s) of reference times ``tau_s`` (s since the first reference sample)."""
        return np.asarray(tau_s, dtype=float) / (1 + self.drift_ppm * 1e-6) - self.offset_s

    def reference_time(self, t_module_s: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`module_time`."""
        return (np.asarray(t_module_s, dtype=float) + self.offset_s) * (1 + self.drift_ppm * 1e-6)


def render_reference(
    motion: Motion,
    world: World,
    mounting: Rotation,
    noise: dict,
    clock: ReferenceClock,
    rate_hz: float,
    ticks_start: int,
    rng: np.random.Generator,
    sample_times: Callable[[np.ndarray], np.ndarray] | None = None,
) -> pd.DataFrame:
    """The reference's export table covering the module recording ``motion``.

    Parameters
    ----------
    motion : Motion
        Motion of B during rotation3d (module clock).
    world : World
    mounting : Rotation
        Reference axes -> B (``v_B = mounting.apply(v_ref)``).
    noise : dict
        White-noise std per sensor (SI).
    clock : ReferenceClock
    rate_hz : float
        Update rate of the reference.
    ticks_start : int
        ``SampleTimeFine`` of the first sample (10 kHz ticks).
    rng : numpy.random.Generator
    sample_times : callable, optional
        Nominal reference times -> the instants the samples are taken at (the effects'
        ``on_reference_times``); the time stamps stay nominal.

    Returns
    -------
    DataFrame
        Columns ``PacketCounter``, ``SampleTimeFine``, ``Acc_X``.. ``Mag_Z`` (SI, the
        magnetometer normalised), one row per reference sample from ``tau = 0`` to the end of
        the module recording on the reference clock.
    """
    n = int(np.floor(clock.reference_time(motion.duration_s) * rate_hz)) + 1
    k = np.arange(n)
    tau = k / rate_hz
    taken = tau if sample_times is None else sample_times(tau)
    signals = true_signals(evaluate_motion(motion, clock.module_time(taken)), world)
    data: dict = {
        REF_COUNTER: k % SEQ_MODULUS,
        REF_TIME_FINE: ticks_start + np.rint(tau * REF_TICKS_PER_S).astype(np.int64),
    }
    for s in SENSORS:
        values = mounting.apply(signals.sensor(s), inverse=True)
        values = values + rng.normal(0.0, noise[s], values.shape)
        data.update(dict(zip(_REF_COLUMNS[s], values.T)))
    return pd.DataFrame(data)


def format_mt_export(table: pd.DataFrame, rate_hz: float) -> str:
    """The MT Manager ASCII export text of a reference table (floats with 6 decimals)."""
    header = "\n".join(_HEADER).format(rate=rate_hz)
    body = table.to_csv(sep="\t", index=False, float_format="%.6f", lineterminator="\n")
    return header + "\n" + body
