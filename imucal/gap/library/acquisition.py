"""Effects of the acquisition: how samples reach the host and how the reference is sampled.

``packet_loss``, ``timing_jitter``, ``time_offset``, ``saturation`` and ``reference_jitter``:
their specs, and the estimators of the full protocol (packet counter, receive timestamps, the
reference clock, clipped readings), of a static recording and of pooled rests (receive latency
above the lower envelope). The reference scope's estimator of ``reference_jitter`` lives with
the statistics it shares (:mod:`imucal.gap.motionstats`).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from scipy.optimize import brentq

from imucal.columns import SENSOR_COLUMNS, SENSORS, SEQ, TIME, column_values
from imucal.gap import locations as loc
from imucal.gap.effects import EffectModel, Estimate
from imucal.gap.library.registry import register
from imucal.gap.library.spec import EffectSpec
from imucal.gap.motionstats import estimate_reference_jitter
from imucal.gap.session import time_half
from imucal.gap.streams import Stream, receive_latency, streams_half
from imucal.pipeline.full import SessionFit
from imucal.sim.effects import stream_rng


def _halves(fit: SessionFit, half):
    return {name: t.iloc[time_half(len(t), half)] for name, t in fit.imu.items()}


def estimate_packet_loss(fit: SessionFit, half) -> Estimate:
    """Lost fraction from the gaps of the 16-bit packet counter, with the mean burst length
    (a Gilbert channel when bursts are longer than 1.2 packets); detect: the fraction."""
    lost = expected = 0
    gaps = []
    for t in _halves(fit, half).values():
        n, e, g = loc.lost_packets(t[SEQ].to_numpy())
        lost, expected = lost + n, expected + e
        gaps.append(g)
    g = np.concatenate(gaps)
    fraction = lost / max(expected, 1)
    burst = float(g.mean()) if len(g) else 1.0
    params = {"fraction": float(fraction), "model": "bernoulli", "burst_mean": 1.0}
    if burst > 1.2:
        burst_cap = max(burst, fraction * 1.01 / max(1 - fraction, 1e-9))
        params.update(model="gilbert", burst_mean=float(burst_cap))
    return Estimate(params, float(fraction))


def estimate_timing_jitter(fit: SessionFit, half) -> Estimate:
    """Std (s) of the receive timestamps about the packet clock's line; detect: the same."""
    res = []
    for t in _halves(fit, half).values():
        r = loc.stamp_residual(t[TIME].to_numpy(dtype=float), t[SEQ].to_numpy())
        res.append(r - np.median(r))
    r = np.concatenate(res)
    std = float(np.std(r))
    return Estimate({"std_s": std}, std)


def estimate_time_offset(fit: SessionFit, half) -> Estimate | None:
    """Offset (s) of the reference clock; detect: ``|offset|``. None without a reference. The
    clocks' rates are ``clock_drift``'s (:func:`estimate_clock_drift`), so that an offset and
    a drift are named each for itself."""
    if fit.time_alignment is None:
        return None
    stats = loc.reference_clock_locations(fit, half)
    offset = stats[("validate", "clock", "-", "rotation3d", "ref_offset_s")]
    return Estimate({"offset_s": float(offset), "drift_ppm": 0.0}, abs(float(offset)))


def estimate_clock_drift(fit: SessionFit, half) -> Estimate | None:
    """Rate error (ppm) of the logger's clock against the reference's, from the time
    alignment's drift (the reference seen from the module's stamps drifts by ``-ppm``);
    detect: ``|drift|``. None without a reference."""
    if fit.time_alignment is None:
        return None
    drift = float(fit.time_alignment.drift_ppm)
    return Estimate({"ppm": -drift}, abs(drift))


def estimate_saturation(fit: SessionFit, half) -> Estimate:
    """Per sensor the range (counts) at its largest reading where readings clip, else int16's;
    detect: the largest clipped fraction."""
    opt = fit.extra["options"]
    params, detect = {}, 0.0
    stats = loc.clipping_locations(fit, half)
    for s in SENSORS:
        frac = stats[("ingest", s, "-", "all", "clip_fraction")]
        top = 32767
        if frac > 0:
            peak = max(
                np.nanmax(np.abs(column_values(t, SENSOR_COLUMNS[s]))) for t in fit.imu.values()
            )
            top = int(np.clip(round(peak / float(opt.sensitivity[s])), 1, 32767))
        params[s] = top
        detect = max(detect, frac)
    return Estimate(params, detect)


def _mean_latency(std_s: float, rate_hz: float, n: int) -> float:
    """Mean latency above the lower envelope of the simulator's jitter model (s)."""
    t = np.arange(n) / rate_hz
    d = stream_rng(0, "calibration/timing_jitter").exponential(std_s, n) if std_s > 0 else 0.0
    lat, _ = receive_latency(np.maximum.accumulate(t + d), rate_hz)
    return float(np.mean(lat))


def estimate_static_timing_jitter(streams: Mapping[str, Stream], half: str | None) -> Estimate:
    """Mean receive latency of the simulator's model that gives the measured mean latency.

    The measured latency is the receive time above the running lower envelope
    (:func:`~imucal.gap.streams.receive_latency`), pooled over the streams; the model's latency
    (exponential, held back by queueing) is solved for by bisection on a noise-free grid of the
    same rate. Detect: the measured mean latency (s).
    """
    lat, n, rate = [], 0, 0.0
    for st in streams_half(streams, half).values():
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


def _rests_latency(std_s: float, shape: list[tuple[int, float]]) -> float:
    """Mean latency above each rest's lower envelope of the simulator's jitter model on
    noise-free grids of the rests' sample counts and rates, pooled over the samples (s)."""
    rng = stream_rng(0, "calibration/timing_jitter")
    total, count = 0.0, 0
    for n, rate in shape:
        t = np.arange(n) / rate
        r = np.maximum.accumulate(t + rng.exponential(std_s, n)) if std_s > 0 else t
        lat, _ = receive_latency(r, (n - 1) / (r[-1] - r[0]))
        total += float(np.sum(lat))
        count += n
    return total / count


def estimate_rest_timing_jitter(session: Mapping[str, Stream], half: str | None) -> Estimate:
    """Mean receive latency of the simulator's model that gives the rests' mean latency.

    The latency above each rest's lower envelope (:func:`~imucal.gap.streams.receive_latency`,
    at the rest's effective rate) pooled over the rests, and the model's (exponential, held
    back by queueing) measured the same way on rests of the same sample counts and rates:
    short rests bias the envelope and the rate, so the model is solved on their own lengths
    (bisection). Detect: the measured mean latency (s; 0 below a nanosecond).
    """
    lat, shape = [], []
    for st in session.values():
        st = st.half(half)
        lat.append(receive_latency(st.t_s, st.rate_hz)[0])
        shape.append((len(st.t_s), st.rate_hz))
    target = float(np.mean(np.concatenate(lat)))
    if target <= 1e-9:  # below a nanosecond: the rounding of regular stamps, not a latency
        return Estimate({"std_s": 0.0}, 0.0)
    hi = 10 * target
    while _rests_latency(hi, shape) < target:
        hi *= 2
    std = brentq(lambda s: _rests_latency(s, shape) - target, 0.0, hi, xtol=1e-6)
    return Estimate({"std_s": float(std)}, target)


_NO_COUNTER = "no packet counter: a lost sample and a late one look the same in receive times"
_NO_REFERENCE = "no reference recording"
_FAR_FROM_RANGES = "a static recording stays far from the ranges"
_NO_ORIENTATION_REFERENCE = "no orientation reference in a static recording"
#: The receive timing of a static recording or of rests, with the static recording's
#: signature (rests: the estimator on their own lengths).
_RECEIVE_LATENCY = (
    ("ingest", "*", "stamp_scatter_s"),
    ("ingest", "*", "stamp_wander_s"),
    ("ingest", "*", "burst_fraction"),
    ("ingest", "*", "long_gap_fraction"),
)
_LATENCY_SEEN = "irregular receive timestamps: host receive latency"

PACKET_LOSS = register(EffectSpec(
    name="packet_loss",
    description="radio packets lost between module and receiver (rows dropped, seq jumps)",
    kind="systematic",
    scopes={
        "protocol": EffectModel("packet_loss", estimate_packet_loss,
                                (("ingest", "clock", "loss_fraction"),),
                                "radio packets lost: gaps in the packet counter"),
        "static": _NO_COUNTER,
        "motion": "no packet counter is compared: a lost sample and a late one look the same",
        "rests": _NO_COUNTER,
        "field_fit": _NO_COUNTER,
    },
))  # fmt: skip

TIMING_JITTER = register(EffectSpec(
    name="timing_jitter",
    description="irregular receive timestamps: each packet stamped after a random latency",
    kind="spread",
    scopes={
        "protocol": EffectModel("timing_jitter", estimate_timing_jitter,
                                (("ingest", "clock", "stamp_scatter_s"),),
                                "irregular receive timestamps about the packet clock"),
        "static": EffectModel("timing_jitter", estimate_static_timing_jitter, _RECEIVE_LATENCY,
                              _LATENCY_SEEN),
        "motion": "no static recording: receive-time statistics need a long regular stream",
        "rests": EffectModel("timing_jitter", estimate_rest_timing_jitter, _RECEIVE_LATENCY,
                             _LATENCY_SEEN),
        "field_fit": "the fit residual does not read the receive times",
    },
))  # fmt: skip

TIME_OFFSET = register(EffectSpec(
    name="time_offset",
    description="offset of the reference clock against the module's",
    kind="systematic",
    scopes={
        "protocol": EffectModel("time_offset", estimate_time_offset,
                                (("validate", "clock", "ref_offset_s"),),
                                "offset of the reference clock against the module"),
        "static": _NO_REFERENCE,
        "motion": "the clock against the reference is measured and removed (validation.json)",
        "rests": _NO_REFERENCE,
        "field_fit": _NO_REFERENCE,
    },
))  # fmt: skip

CLOCK_DRIFT = register(EffectSpec(
    name="clock_drift",
    description="the logger's clock and the reference's run at rates some ppm apart",
    kind="systematic",
    scopes={
        "protocol": EffectModel("clock_drift", estimate_clock_drift,
                                (("validate", "clock", "ref_drift_ppm"),),
                                "rate error of the logger's clock against the reference's"),
        "static": "no reference recording: the stamps' rate against the packet counter is the "
        "module's sample rate as much as the logger's clock",
        "motion": "the clock against the reference is measured and removed (validation.json)",
        "rests": _NO_REFERENCE,
        "field_fit": _NO_REFERENCE,
    },
))  # fmt: skip

SATURATION = register(EffectSpec(
    name="saturation",
    description="sensors clip at a range smaller than int16",
    kind="systematic",
    scopes={
        "protocol": EffectModel("saturation", estimate_saturation,
                                (("ingest", "*", "clip_fraction"),
                                 ("gyr_table", "gyr", "left_out")),
                                "samples clipped at the sensor range"),
        "static": _FAR_FROM_RANGES,
        "motion": "clipping shows in the readings themselves (ingest summary), not against a "
        "reference",
        "rests": _FAR_FROM_RANGES,
        "field_fit": _FAR_FROM_RANGES,
    },
))  # fmt: skip

REFERENCE_JITTER = register(EffectSpec(
    name="reference_jitter",
    description="the reference's samples taken at their nominal time stamps plus white jitter",
    kind="spread",
    scopes={
        "protocol": "the MT Manager reference is aligned by its clock (offset and drift), not "
        "compared sample by sample with the gyroscope",
        "static": _NO_ORIENTATION_REFERENCE,
        "motion": EffectModel("reference_jitter", estimate_reference_jitter,
                              (("reference", "gyr", "resid_rms"),
                               ("reference", "gyr", "ori_median_rad"),
                               # its rate errors grow with the rate: the residual's slopes on
                               # the rate's square and cube move with them
                               ("reference", "gyr", "rate2"), ("reference", "gyr", "rate3")),
                              "the reference's samples taken off their time stamps (an error "
                              "growing with rate)"),
        "rests": _NO_ORIENTATION_REFERENCE,
        "field_fit": _NO_ORIENTATION_REFERENCE,
    },
))  # fmt: skip
