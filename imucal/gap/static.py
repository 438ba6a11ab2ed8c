"""The sim-to-real gap of a session off the paper's protocol, on what its static recording shows.

A partial session (:mod:`imucal.pipeline.partial`) has no cube, rate table or reference, so the
full-protocol diagnosis (:func:`imucal.gap.diagnosis.diagnose`) cannot refit it. What such a
session usually does have is a long ``static`` recording, and that is where this diagnosis
looks, with the definitions of :mod:`imucal.gap`: the twin is
:class:`~imucal.gap.statictwin.StaticTwin`, the locations are those of :mod:`imucal.gap.streams`, the
null, scores, attribution and ``diagnosis.json`` are :func:`imucal.gap.scoring.scored_diagnosis`
as for a full session.

This module holds what is particular to a static recording: the effects it can show
(:data:`STATIC_LIBRARY`), each an :class:`~imucal.gap.effects.EffectModel` whose estimator
reads the recording's streams (``timing_jitter``: host receive latency; ``bias_instability``:
Allan excess; ``temperature_drift``: biases following the temperature channel), and the effects
it cannot show, with the reason (:data:`NOT_OBSERVABLE`).
"""

from __future__ import annotations

import time
from collections.abc import Mapping

import numpy as np
import pandas as pd
from scipy.optimize import brentq, curve_fit

from imucal.columns import SENSORS
from imucal.constants import STANDARD_GRAVITY_M_S2
from imucal.gap.effects import EffectModel, Estimate
from imucal.gap.locations import allan_deviation
from imucal.gap.scoring import FORMAT_VERSION, DiagnosisSettings, scope_diagnosis
from imucal.gap.statictwin import build_static_twin
from imucal.gap.statistics import HALVES
from imucal.gap.streams import (
    Stream,
    receive_latency,
    split_streams,
    static_statistics,
    temperature_slopes,
    white_std,
)
from imucal.sim.effects import stream_rng

#: Effects of the library a single static recording cannot show, and why.
NOT_OBSERVABLE = {
    "packet_loss": "no packet counter: a lost sample and a late one look the same in receive times",
    "time_offset": "no reference recording",
    "mag_latency": "no rotation in a static recording: a magnetometer lag does not show",
    "lever_arm": "no rotation in a static recording",
    "g_sensitivity": "one orientation only: a g-dependent gyro bias is a constant bias",
    "earth_rotation": "one orientation only: the Earth's rate is part of the constant bias",
    "saturation": "a static recording stays far from the ranges",
    "scale_nonlinearity": "one input level per axis in a static recording",
    "world_magnetic": "one position and attitude: a field fixed in the world is part of the "
    "constant field",
    "shock": "no estimator on a static recording's streams (its statistics are Allan "
    "deviations and receive times, which do not isolate a few spikes); recordings with an "
    "orientation reference show knocks",
    "vibration": "no estimator on a static recording's streams (no spectral line statistic); "
    "recordings with an orientation reference show a line",
    "hand_tremor": "a static recording lies still; holds held by hand are the segmentation's",
    "platform_magnetic": "no platform activity in a static recording: its field is constant",
    "placement_error": "one pose: a tilt from a nominal direction needs a second pose",
    "large_misalignment": "no rotation: the alignment T_R is not fitted on a static recording",
    "reference_jitter": "no orientation reference in a static recording",
}


def _half(streams: Mapping[str, Stream], half: str | None) -> dict[str, Stream]:
    return {k: s.half(half) for k, s in streams.items()}


def _mean_latency(std_s: float, rate_hz: float, n: int) -> float:
    """Mean latency above the lower envelope of the simulator's jitter model (s)."""
    t = np.arange(n) / rate_hz
    d = stream_rng(0, "calibration/timing_jitter").exponential(std_s, n) if std_s > 0 else 0.0
    lat, _ = receive_latency(np.maximum.accumulate(t + d), rate_hz)
    return float(np.mean(lat))


def estimate_timing_jitter(streams: Mapping[str, Stream], half: str | None) -> Estimate:
    """Mean receive latency of the simulator's model that gives the measured mean latency.

    The measured latency is the receive time above the running lower envelope
    (:func:`~imucal.gap.streams.receive_latency`), pooled over the streams; the model's latency
    (exponential, held back by queueing) is solved for by bisection on a noise-free grid of the
    same rate. Detect: the measured mean latency (s).
    """
    lat, n, rate = [], 0, 0.0
    for st in _half(streams, half).values():
        lat.append(receive_latency(st.t_s, st.rate_hz)[0])
        if len(st.t_s) > n:
            n, rate = len(st.t_s), st.rate_hz
    target = float(np.mean(np.concatenate(lat)))
    n_model = min(n, 20000)
    if target <= 1e-9:
        return Estimate({"std_s": 0.0}, target)
    hi = 10 * target
    while _mean_latency(hi, rate, n_model) < target:
        hi *= 2
    std = brentq(lambda s: _mean_latency(s, rate, n_model) - target, 0.0, hi, xtol=1e-6)
    return Estimate({"std_s": float(std)}, target)


def _gm_from_allan(x: np.ndarray, rate_hz: float) -> tuple[float, float]:
    """Gauss-Markov std (SI) from the Allan excess at ``min(100 s, T/5)``, and its log ratio."""
    white = white_std(x)
    tau = min(100.0, len(x) / rate_hz / 5)
    m = max(int(tau * rate_hz), 1)
    ad = allan_deviation(x, m)
    excess = np.maximum(ad**2 - white**2 / m, 0.0)
    # a first-order Gauss-Markov process's Allan deviation peaks near 0.62 of its std
    return float(np.sqrt(np.mean(excess))) / 0.62, float(np.mean(np.log(ad / (white / np.sqrt(m)))))


def estimate_bias_instability(streams: Mapping[str, Stream], half: str | None) -> Estimate:
    """Gauss-Markov bias std per sensor from the Allan excess; detect: mean log excess.

    The simulator's process has one std per sensor (all axes); the estimate pools the axes'
    excess variance. A magnetometer's "bias" wander includes changes of the ambient field.
    """
    streams = _half(streams, half)
    params, detect = {}, []
    for s in SENSORS:
        st = next((st for st in streams.values() if s in st.values), None)
        gm = 0.0
        if st is not None:
            gm, lr = _gm_from_allan(st.values[s], st.rate_hz)
            detect.append(lr)
        params.update({f"{s}_rw": 0.0, f"{s}_gm": gm, f"{s}_tau_s": 100.0})
    return Estimate(params, float(np.mean(detect)))


def estimate_temperature_drift(streams: Mapping[str, Stream], half: str | None) -> Estimate | None:
    """Warm-up curve of the temperature channel and the bias per kelvin of each axis.

    The per-axis slopes of the block means on the temperature
    (:func:`~imucal.gap.streams.temperature_slopes`) are the simulator's per-axis bias drift
    (either sign; the parameterisation of the model term's polynomial at order 1); one
    orientation shows no scale drift (its input does not change), so the scales are 0.
    Detect: the largest |gyro slope| over the axes (rad/s/K).
    """
    imu = streams.get("imu")
    if imu is None:
        return None
    imu = imu.half(half)
    slopes = temperature_slopes(imu)
    if not slopes:
        return None
    t = imu.t_s - imu.t_s[0]
    temp = imu.temperature_c

    def warm(tt, start, rise, tau):
        return start + rise * (1 - np.exp(-tt / tau))

    try:
        (start, rise, tau), _ = curve_fit(
            warm, t, temp, p0=(temp[0], temp[-1] - temp[0], t[-1] / 3), maxfev=4000
        )
        if not (tau > 0 and np.isfinite(rise)):
            raise RuntimeError("warm-up fit diverged")
    except RuntimeError:
        # a straight line: the exponential with a time constant far beyond the recording
        slope = np.polyfit(t, temp, 1)
        tau = 1e3 * t[-1]
        start, rise = slope[1], slope[0] * tau
    params = {
        "start_c": float(start), "rise_c": float(rise), "tau_s": float(tau),
        "acc_per_k": [float(v) for v in slopes.get("acc", np.zeros(3))],
        "gyr_per_k": [float(v) for v in slopes.get("gyr", np.zeros(3))],
        "mag_per_k": [0.0] * 3, "acc_scale_per_k": [0.0] * 3, "gyr_scale_per_k": [0.0] * 3,
        "mag_scale_per_k": [0.0] * 3,
    }  # fmt: skip
    return Estimate(params, float(np.max(np.abs(slopes.get("gyr", np.zeros(3))))))


#: Effects a static recording can show, with the locations each should move.
STATIC_LIBRARY = {
    m.name: m
    for m in (
        EffectModel("timing_jitter", estimate_timing_jitter,
                    (("ingest", "*", "stamp_scatter_s"), ("ingest", "*", "burst_fraction"),
                     ("ingest", "*", "long_gap_fraction")),
                    "irregular receive timestamps: host receive latency"),
        EffectModel("bias_instability", estimate_bias_instability,
                    (("noise", "*", "adev_10s_excess"), ("noise", "*", "adev_long_excess"),
                     ("noise", "*", "trend_per_s")),
                    "wandering biases: Allan deviation above the white-noise line"),
        EffectModel("temperature_drift", estimate_temperature_drift,
                    (("temperature", "*", "temp_slope"), ("noise", "*", "trend_per_s"),
                     ("noise", "*", "adev_long_excess")),
                    "biases following the temperature channel"),
    )
}  # fmt: skip


def unscored_diagnosis(dataset: str, reason: str) -> dict:
    """diagnosis.json of a session where no location can be scored, saying why."""
    return {
        "format_version": FORMAT_VERSION,
        "dataset": dataset,
        "gap": {"total": None, "null_p95": None, "significant": False},
        "locations": [],
        "effects": [],
        "explained": [],
        "remaining": {"total": None, "significant": False, "locations": []},
        "scope": "none",
        "reason": reason,
        "confusable": [],
        "all_locations": [],
        "null": {},
    }


def diagnose_static(
    table: pd.DataFrame,
    *,
    dataset: str,
    calibration: Mapping | None = None,
    sensitivity: Mapping[str, float] | None = None,
    gravity_m_s2: float = STANDARD_GRAVITY_M_S2,
    settings: DiagnosisSettings = DiagnosisSettings(),
    wander: bool = True,
) -> dict:
    """The gap diagnosis of a partial session from its static recording.

    Parameters
    ----------
    table : DataFrame
        The ingested ``static`` recording (rows in receive order, SI).
    dataset : str
    calibration : dict, optional
        The session's calibration JSON (``partial/calibration.json``).
    sensitivity : dict, optional
        SI per count per sensor from dataset.yaml (estimated from the data where absent).
    gravity_m_s2 : float
    settings : DiagnosisSettings
        As for a full session; ``exclude`` leaves effects out of :data:`STATIC_LIBRARY`.
    wander : bool
        As :func:`~imucal.gap.statictwin.build_static_twin` (False: the twin's noise is white
        and a wandering bias is the effect ``bias_instability``).

    Returns
    -------
    dict
        diagnosis.json (:func:`~imucal.gap.scoring.scored_diagnosis`) plus ``scope``,
        ``not_observable``, ``twin``, ``settings``, ``timing_s``.

    Raises
    ------
    ValueError
        If the recording has no stream of 100 rows.
    """
    t0 = time.perf_counter()
    streams = split_streams(table)
    if not streams:
        raise ValueError(
            "the static recording has no acc/gyro or magnetometer stream of >= 100 rows"
        )
    stats = {h: static_statistics(streams, h) for h in HALVES}
    twin = build_static_twin(streams, calibration, dict(sensitivity or {}), gravity_m_s2, wander)
    return scope_diagnosis(
        twin, streams, stats, STATIC_LIBRARY, scope="static", not_observable=NOT_OBSERVABLE,
        cannot_show="the session cannot show this effect (no such stream or channel)",
        dataset=dataset, settings=settings, started=t0,
    )  # fmt: skip
