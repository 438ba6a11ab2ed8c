"""The sim-to-real gap of a session off the paper's protocol, on what its static recording shows.

A partial session (:mod:`imucal.pipeline.partial`) has no cube, rate table or reference, so the
full-protocol diagnosis (:func:`imucal.gap.diagnose`) cannot refit it. What such a session
usually does have is a long ``static`` recording, and that is where this diagnosis looks. The
definitions are those of :mod:`imucal.gap`:

* **Twin** (:class:`StaticTwin`): the simulator (:mod:`imucal.sim`: the ``static`` plan's
  ``hold``, the sensor model, quantisation, the effects' hooks) configured with the session's
  fitted calibration (identity for a sensor the session could not calibrate: static statistics
  are about noise and drift, not about the mean), white noise estimated from the static
  readings, and the session's own timing: the number of samples and effective rate
  ``(n - 1) / duration`` of the acc/gyro stream and of the magnetometer stream, and its
  temperature channel carried over by time. No effect beyond the paper's model: regular sample
  times, no loss, constant biases.
* **Locations**: ``static`` stage x sensor x axis x segment ``static`` x statistic. Timing per
  stream (``imu``: acc/gyro rows; ``mag``): the receive latency above the stream's lower
  envelope (``stamp_scatter_s``), the wander of that envelope about the straight clock line
  (``stamp_wander_s``), the fraction of intervals shorter than a quarter period
  (``burst_fraction``, samples delivered back to back) and longer than three periods
  (``long_gap_fraction``). Noise per sensor axis: Allan deviation at 10 s and at a fifth of the
  recording as log-ratio to the white-noise line, and the linear trend, all on the stream's
  sample index (the receive times are not the sample times). Temperature channel: slope of
  block means on the block-mean temperature per acc and gyro axis. Halves A/B are the first
  and second half of the recording in time.
* **Null, scores, total gap**: replicas of the twin with fresh seeds measured by the same
  code; scored, Holm-corrected and summed by :mod:`imucal.gap.null`.
* **Effects** a static recording can show: ``timing_jitter`` (host receive latency),
  ``bias_instability`` (Allan excess), ``temperature_drift`` (biases following the
  temperature channel). Each has an estimator from the session, a detection statistic scored
  against the replicas, and is added to the twin at its estimate (common random numbers); the
  held-out shrink uses parameters from half A and the gap of half B; forward selection as in
  :mod:`imucal.gap.attribution`. Effects a static recording cannot show are listed with the
  reason.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.ndimage import minimum_filter1d
from scipy.optimize import brentq, curve_fit

from imucal.calibration import ImuCalibration, SensorCalibration
from imucal.columns import AXES, SENSOR_COLUMNS, SENSORS, TIME
from imucal.constants import STANDARD_GRAVITY_M_S2
from imucal.gap.attribution import (
    Candidate,
    confusable,
    detection_z,
    select_forward,
    statistic_shift,
)
from imucal.gap.diagnosis import FORMAT_VERSION, LOCATION_FIELDS
from imucal.gap.null import NullModel, holm, transform
from imucal.gap.statistics import (
    CATALOGUE,
    HALVES,
    StatisticInfo,
    allan_deviation,
    temperature_column,
)
from imucal.sim.effects import RecordingContext, make_effect, stream_rng
from imucal.sim.motion import evaluate_motion
from imucal.sim.packets import build_packet_log
from imucal.sim.protocol import ProtocolConfig, plan_static
from imucal.sim.sensors import quantise, sensor_readings, true_signals
from imucal.sim.truth import REFERENCE_NOISE, Truth, World

#: Statistics of the static diagnosis that the full-protocol catalogue does not have; they join
#: :data:`imucal.gap.statistics.CATALOGUE` so that the null's scoring (log transform, resolution
#: floor) applies to them unchanged.
STATIC_CATALOGUE = {
    "stamp_wander_s": StatisticInfo("s", log=True, floor=0.05),
    "burst_fraction": StatisticInfo("1", floor=2e-3),
    "long_gap_fraction": StatisticInfo("1", floor=2e-4),
}
for _name, _info in STATIC_CATALOGUE.items():
    CATALOGUE.setdefault(_name, _info)

#: Sensor of each stream of a static recording.
STREAMS = {"imu": ("acc", "gyr"), "mag": ("mag",)}
#: Window of the lower envelope of the receive times (s): longer than a latency burst, shorter
#: than the wander of the host clock against the sample clock.
ENVELOPE_S = 10.0
#: Blocks of the static recording for the temperature regression.
TEMPERATURE_BLOCKS = 16
#: Smallest resolution of a synthetic quantiser: counts must fit the int16 range.
INT16_HEADROOM = 30000.0
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
}


# --------------------------------------------------------------------------------------------
# The static recording as streams


@dataclass(frozen=True)
class Stream:
    """One stream of a static recording: its rows in receive order.

    Attributes
    ----------
    t_s : ndarray, shape (n,)
        Receive times (s).
    values : dict
        Sensor -> ndarray, shape (n, 3), SI.
    temperature_c : ndarray, shape (n,), or None
    """

    t_s: np.ndarray
    values: dict
    temperature_c: np.ndarray | None = None

    @property
    def rate_hz(self) -> float:
        """Effective sample rate ``(n - 1) / duration`` (Hz)."""
        return (len(self.t_s) - 1) / (self.t_s[-1] - self.t_s[0])

    def half(self, half: str | None) -> Stream:
        if half is None:
            return self
        n = len(self.t_s)
        sl = slice(0, n // 2) if half == "A" else slice(n // 2, n)
        temp = None if self.temperature_c is None else self.temperature_c[sl]
        return Stream(self.t_s[sl], {s: v[sl] for s, v in self.values.items()}, temp)


def split_streams(table: pd.DataFrame) -> dict[str, Stream]:
    """The acc/gyro and magnetometer streams of an ingested static recording.

    Parameters
    ----------
    table : DataFrame
        Ingested recording (``t_s``, sensor columns with NaN where a row has no sample of that
        sensor, optionally a temperature column).

    Returns
    -------
    dict
        ``'imu'`` and/or ``'mag'`` -> :class:`Stream` (a stream needs at least 100 rows).
    """
    out = {}
    t = table[TIME].to_numpy(dtype=float)
    col = temperature_column(table)
    for name, sensors in STREAMS.items():
        present = [s for s in sensors if all(c in table.columns for c in SENSOR_COLUMNS[s])]
        if not present:
            continue
        x = {s: table[list(SENSOR_COLUMNS[s])].to_numpy(dtype=float) for s in present}
        rows = np.all(np.column_stack([np.isfinite(v) for v in x.values()]), axis=1)
        if rows.sum() < 100:
            continue
        temp = None
        if name == "imu" and col is not None:
            temp_all = table[col].to_numpy(dtype=float)
            ok = rows & np.isfinite(temp_all)
            if ok.sum() == rows.sum():
                temp = temp_all[rows]
        out[name] = Stream(t[rows], {s: v[rows] for s, v in x.items()}, temp)
    return out


# --------------------------------------------------------------------------------------------
# Statistics


def receive_latency(t_s: np.ndarray, rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """Split receive times into a latency above the lower envelope and the envelope's wander.

    Parameters
    ----------
    t_s : ndarray, shape (n,)
        Receive times (s) of consecutive samples.
    rate_hz : float
        Effective sample rate.

    Returns
    -------
    latency : ndarray, shape (n,)
        ``r - envelope`` (s, >= 0) with ``r`` the residual about the straight line
        ``t_0 + k / rate`` and ``envelope`` its running minimum over :data:`ENVELOPE_S`.
    wander : ndarray, shape (n,)
        The envelope about its mean (s): the host clock against the sample clock.
    """
    k = np.arange(len(t_s))
    r = t_s - t_s[0] - k / rate_hz
    w = max(int(ENVELOPE_S * rate_hz) | 1, 3)
    env = minimum_filter1d(r, w, mode="nearest")
    return r - env, env - env.mean()


def timing_statistics(stream: Stream, name: str) -> dict:
    """Timing locations of one stream (see the module docstring)."""
    t = stream.t_s
    rate = stream.rate_hz
    latency, wander = receive_latency(t, rate)
    d = np.diff(t) * rate
    key = ("ingest", "clock", name, "static")
    return {
        (*key, "stamp_scatter_s"): float(max(np.sqrt(np.mean(latency**2)), 1e-7)),
        (*key, "stamp_wander_s"): float(max(np.sqrt(np.mean(wander**2)), 1e-7)),
        (*key, "burst_fraction"): float(np.mean(d < 0.25)),
        (*key, "long_gap_fraction"): float(np.mean(d > 3.0)),
    }


def white_std(x: np.ndarray) -> np.ndarray:
    """White-noise std per axis from first differences, shape (3,) (SI)."""
    return np.std(np.diff(x, axis=0), axis=0) / np.sqrt(2)


def noise_statistics(stream: Stream) -> dict:
    """Allan-deviation excess at 10 s and at a fifth of the recording, and the trend."""
    rate = stream.rate_hz
    out = {}
    for s, x in stream.values.items():
        n = len(x)
        tk = np.arange(n) / rate
        white = white_std(x)
        slope = np.polyfit(tk - tk.mean(), x, 1)[0]
        m10 = max(int(round(10 * rate)), 1)
        mlong = max(n // 5, 1)
        ad10, adl = allan_deviation(x, m10), allan_deviation(x, mlong)
        for j, a in enumerate(AXES):
            key = ("noise", s, a, "static")
            out[(*key, "adev_10s_excess")] = float(np.log(ad10[j] / (white[j] / np.sqrt(m10))))
            out[(*key, "adev_long_excess")] = float(np.log(adl[j] / (white[j] / np.sqrt(mlong))))
            out[(*key, "trend_per_s")] = float(slope[j])
    return out


def temperature_slopes(stream: Stream) -> dict[str, np.ndarray]:
    """Slope of block means on block-mean temperature, per sensor (SI/K), each shape (3,).

    Empty when the stream has no temperature channel or it does not change.
    """
    if stream.temperature_c is None:
        return {}
    edges = np.linspace(0, len(stream.t_s), TEMPERATURE_BLOCKS + 1).astype(int)
    temp = np.array([stream.temperature_c[a:b].mean() for a, b in zip(edges[:-1], edges[1:])])
    x = temp - temp.mean()
    if not x @ x > 0:
        return {}
    out = {}
    for s in ("acc", "gyr"):
        if s not in stream.values:
            continue
        v = stream.values[s]
        means = np.array([v[a:b].mean(axis=0) for a, b in zip(edges[:-1], edges[1:])])
        out[s] = x @ (means - means.mean(axis=0)) / (x @ x)
    return out


def static_statistics(streams: Mapping[str, Stream], half: str | None = None) -> dict:
    """Every location of a static recording (see the module docstring).

    Parameters
    ----------
    streams : dict
        Output of :func:`split_streams` (or of a twin replica).
    half : {None, 'A', 'B'}
        The whole recording, or its first / second half in time.

    Returns
    -------
    dict
        ``(stage, sensor, axis, segment, statistic)`` -> value (units in the catalogue).
    """
    out = {}
    for name, stream in streams.items():
        s = stream.half(half)
        out.update(timing_statistics(s, name))
        out.update(noise_statistics(s))
        for sensor, slope in temperature_slopes(s).items():
            for j, a in enumerate(AXES):
                out[("temperature", sensor, a, "static", "temp_slope")] = float(slope[j])
    return out


# --------------------------------------------------------------------------------------------
# The twin


@dataclass(frozen=True)
class StaticTwin:
    """Everything a replica of a static recording is rendered from.

    Attributes
    ----------
    truth : Truth
        Calibration = the session's (identity where it has none); white noise per sensor.
    sensitivity : dict
        Sensor -> quantisation step (SI per count), from dataset.yaml or the data.
    streams : dict
        Stream name -> (number of samples, effective rate in Hz).
    temperature : tuple of ndarray or None
        (time since the first sample (s), temperature (deg C)) of the acc/gyro stream, carried
        over to the replicas by time.
    notes : list of str
    """

    truth: Truth
    sensitivity: dict
    streams: dict
    temperature: tuple | None = None
    notes: list = field(default_factory=list)

    @property
    def duration_s(self) -> float:
        return max((n - 1) / rate for n, rate in self.streams.values())

    def describe(self) -> dict:
        """JSON-ready summary."""
        return {
            "noise": {k: float(v) for k, v in self.truth.noise.items()},
            "sensitivity": {k: float(v) for k, v in self.sensitivity.items()},
            "streams": {
                k: {"samples": int(n), "rate_hz": float(r)} for k, (n, r) in self.streams.items()
            },
            "duration_s": self.duration_s,
            "temperature_channel": self.temperature is not None,
            "notes": list(self.notes),
        }


def quantum(x: np.ndarray) -> float:
    """Quantisation step of readings (SI), from the smallest common difference of their values.

    The 5th percentile of the positive differences between sorted distinct values of each axis
    (rounding noise of a unit conversion is far below it), and never so small that the range of
    ``x`` would not fit :data:`INT16_HEADROOM` counts.
    """
    steps = []
    for j in range(x.shape[1]):
        u = np.unique(x[:, j])
        d = np.diff(u)
        d = d[d > 1e-12 * max(np.max(np.abs(u)), 1e-30)]
        if len(d):
            steps.append(np.percentile(d, 5))
    q = float(min(steps)) if steps else 0.0
    return max(q, float(np.max(np.abs(x))) / INT16_HEADROOM)


def _identity(sensor: str) -> SensorCalibration:
    unit = {"acc": "m/s^2", "gyr": "rad/s", "mag": "normalised"}[sensor]
    return SensorCalibration(sensor, np.zeros(3), np.eye(3), unit, method="identity (twin)")


def build_static_twin(
    streams: Mapping[str, Stream],
    calibration: Mapping | None,
    sensitivity: Mapping[str, float],
    gravity_m_s2: float,
) -> StaticTwin:
    """The twin of a static recording (see the module docstring).

    Parameters
    ----------
    streams : dict
        Output of :func:`split_streams`.
    calibration : dict or None
        The session's calibration JSON (``partial/calibration.json``): sensors it holds are
        used, the others are identity.
    sensitivity : dict
        SI per count from dataset.yaml (may be empty: then estimated from the readings).
    gravity_m_s2 : float

    Returns
    -------
    StaticTwin
    """
    notes = []
    cals = {}
    for s in SENSORS:
        if calibration and isinstance(calibration.get(s), dict) and "matrix" in calibration[s]:
            cals[s] = SensorCalibration.from_dict(s, calibration[s])
            notes.append(f"{s}: the session's fitted calibration ({cals[s].method})")
        else:
            cals[s] = _identity(s)
    noise, sens = {}, {}
    for name, stream in streams.items():
        for s, x in stream.values.items():
            q = float(sensitivity.get(s) or quantum(x))
            if not sensitivity.get(s):
                notes.append(f"{s}: quantisation step {q:.4g} SI estimated from the readings")
            var = np.mean(white_std(x) ** 2) - q**2 / 12
            noise[s], sens[s] = float(np.sqrt(max(var, 0.0))), q
    missing = [s for s in SENSORS if s not in noise]
    for s in missing:  # not rendered into any stream; the simulator needs a value
        noise[s], sens[s] = 0.0, 1e-3
    notes.append("noise: std of first differences / sqrt(2), quantisation removed, axes pooled")
    notes.append("timing: regular sample times at each stream's effective rate, no loss")
    truth = Truth(
        calibration=ImuCalibration(cals["acc"], cals["gyr"], cals["mag"]),
        world=World(gravity_m_s2=gravity_m_s2),
        noise=noise,
        reference_noise=dict(REFERENCE_NOISE),
        mounting_rotvec_rad=np.zeros(3),
        preset="twin",
    )
    temp = None
    imu = streams.get("imu")
    if imu is not None and imu.temperature_c is not None:
        temp = (imu.t_s - imu.t_s[0], imu.temperature_c)
        notes.append("temperature channel carried over by time")
    spec = {name: (len(st.t_s), st.rate_hz) for name, st in streams.items()}
    return StaticTwin(truth, sens, spec, temp, notes)


def render_static(twin: StaticTwin, seed: int, effects: tuple = ()) -> dict[str, Stream]:
    """One replica of the static recording, as streams.

    The simulator's ``static`` plan (a ``hold``) is evaluated at each stream's sample times
    ``k / rate``; sensor readings, quantisation and packets go through :mod:`imucal.sim` with
    the effects' hooks (``on_truth``, ``on_true_signals``, ``on_readings``, ``on_packets``).
    Each stream is a recording of its own for the random streams (``static/imu``,
    ``static/mag``).

    Parameters
    ----------
    twin : StaticTwin
    seed : int
    effects : tuple of Effect

    Returns
    -------
    dict
        Stream name -> :class:`Stream`.
    """
    truth = twin.truth
    for effect in effects:
        truth = effect.on_truth(truth)
    plan = plan_static(ProtocolConfig(static_s=twin.duration_s + 1.0), stream_rng(seed, "protocol"))
    out = {}
    for name, (n, rate) in twin.streams.items():
        rec = f"static/{name}"
        ctx = RecordingContext(
            rec, rate, 0.0, twin.sensitivity, seed, plan.motion, truth.calibration, {}
        )
        state = evaluate_motion(plan.motion, np.arange(n) / rate)
        true = true_signals(state, truth.world)
        for effect in effects:
            true = effect.on_true_signals(true, state, ctx)
        readings = sensor_readings(
            truth.calibration, true, truth.noise, stream_rng(seed, f"noise/{rec}")
        )
        for effect in effects:
            readings = effect.on_readings(readings, true, state, ctx)
        counts = {s: quantise(readings.sensor(s), twin.sensitivity[s])[0] for s in SENSORS}
        log = build_packet_log(counts, 0, rate, mag_every=1)
        for effect in effects:
            log = effect.on_packets(log, ctx)
        values = {s: log.counts[s] * twin.sensitivity[s] for s in STREAMS[name]}
        temp = None
        if name == "imu":
            if "temp_c" in log.extra:
                temp = np.asarray(log.extra["temp_c"], dtype=float)
            elif twin.temperature is not None:
                temp = np.interp(log.sample / rate, *twin.temperature)
        out[name] = Stream(np.asarray(log.t_s, dtype=float), values, temp)
    return out


# --------------------------------------------------------------------------------------------
# Effects a static recording can show


@dataclass(frozen=True)
class StaticEffect:
    """One effect of the static diagnosis.

    Attributes
    ----------
    name : str
        Canonical effect name (also the simulator effect's).
    estimate : callable
        ``(streams) -> (params, detect)`` or None (the session cannot show the effect).
    signature : tuple of (stage, statistic)
    """

    name: str
    estimate: Callable
    signature: tuple

    def matches(self, key: tuple) -> bool:
        return any(key[0] == stage and key[4] == stat for stage, stat in self.signature)


def _mean_latency(std_s: float, rate_hz: float, n: int) -> float:
    """Mean latency above the lower envelope of the simulator's jitter model (s)."""
    t = np.arange(n) / rate_hz
    d = stream_rng(0, "calibration/timing_jitter").exponential(std_s, n) if std_s > 0 else 0.0
    lat, _ = receive_latency(np.maximum.accumulate(t + d), rate_hz)
    return float(np.mean(lat))


def estimate_timing_jitter(streams: Mapping[str, Stream]) -> tuple[dict, float] | None:
    """Mean receive latency of the simulator's model that gives the measured mean latency.

    The measured latency is the receive time above the running lower envelope
    (:func:`receive_latency`), pooled over the streams; the model's latency (exponential, held
    back by queueing) is solved for by bisection on a noise-free grid of the same rate.
    """
    lat, n, rate = [], 0, 0.0
    for st in streams.values():
        lat.append(receive_latency(st.t_s, st.rate_hz)[0])
        if len(st.t_s) > n:
            n, rate = len(st.t_s), st.rate_hz
    target = float(np.mean(np.concatenate(lat)))
    n_model = min(n, 20000)
    if target <= 1e-9:
        return {"std_s": 0.0}, target
    hi = 10 * target
    while _mean_latency(hi, rate, n_model) < target:
        hi *= 2
    std = brentq(lambda s: _mean_latency(s, rate, n_model) - target, 0.0, hi, xtol=1e-6)
    return {"std_s": float(std)}, target


def _gm_from_allan(x: np.ndarray, rate_hz: float) -> tuple[float, float]:
    """Gauss-Markov std (SI) from the Allan excess at ``min(100 s, T/5)``, and its log ratio."""
    white = white_std(x)
    tau = min(100.0, len(x) / rate_hz / 5)
    m = max(int(tau * rate_hz), 1)
    ad = allan_deviation(x, m)
    excess = np.maximum(ad**2 - white**2 / m, 0.0)
    # a first-order Gauss-Markov process's Allan deviation peaks near 0.62 of its std
    return float(np.sqrt(np.mean(excess))) / 0.62, float(np.mean(np.log(ad / (white / np.sqrt(m)))))


def estimate_bias_instability(streams: Mapping[str, Stream]) -> tuple[dict, float] | None:
    """Gauss-Markov bias std per sensor from the Allan excess; detect: mean log excess.

    The simulator's process has one std per sensor (all axes); the estimate pools the axes'
    excess variance. A magnetometer's "bias" wander includes changes of the ambient field.
    """
    params, detect = {}, []
    for s in SENSORS:
        st = next((st for st in streams.values() if s in st.values), None)
        gm = 0.0
        if st is not None:
            gm, lr = _gm_from_allan(st.values[s], st.rate_hz)
            detect.append(lr)
        params.update({f"{s}_rw": 0.0, f"{s}_gm": gm, f"{s}_tau_s": 100.0})
    return params, float(np.mean(detect))


def estimate_temperature_drift(streams: Mapping[str, Stream]) -> tuple[dict, float] | None:
    """Warm-up curve of the temperature channel and the bias per kelvin per sensor.

    The simulator's effect drifts all three axes of a sensor by the same ``per_k``; the
    least-squares value is the mean of the per-axis slopes. Detect: the largest |gyro slope|
    over the axes (rad/s/K).
    """
    imu = streams.get("imu")
    if imu is None:
        return None
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
        "acc_per_k": float(np.mean(slopes.get("acc", np.zeros(3)))),
        "gyr_per_k": float(np.mean(slopes.get("gyr", np.zeros(3)))),
        "mag_per_k": 0.0, "acc_scale_per_k": 0.0, "gyr_scale_per_k": 0.0, "mag_scale_per_k": 0.0,
    }  # fmt: skip
    return params, float(np.max(np.abs(slopes.get("gyr", np.zeros(3)))))


STATIC_LIBRARY = {
    e.name: e
    for e in (
        StaticEffect("timing_jitter", estimate_timing_jitter,
                     (("ingest", "stamp_scatter_s"), ("ingest", "burst_fraction"),
                      ("ingest", "long_gap_fraction"))),
        StaticEffect("bias_instability", estimate_bias_instability,
                     (("noise", "adev_10s_excess"), ("noise", "adev_long_excess"),
                      ("noise", "trend_per_s"))),
        StaticEffect("temperature_drift", estimate_temperature_drift,
                     (("temperature", "temp_slope"), ("noise", "trend_per_s"),
                      ("noise", "adev_long_excess"))),
    )
}  # fmt: skip


# --------------------------------------------------------------------------------------------
# Null, attribution, diagnosis


@dataclass(frozen=True)
class StaticReplica:
    seed: int
    streams: dict
    stats: dict


def run_static_replica(twin: StaticTwin, seed: int, effects: tuple = ()) -> StaticReplica:
    streams = render_static(twin, seed, effects)
    return StaticReplica(seed, streams, {h: static_statistics(streams, h) for h in HALVES})


def _null(replicas, half, keys) -> NullModel:
    values = np.array(
        [[transform(k, r.stats[half].get(k, np.nan)) for k in keys] for r in replicas]
    )
    return NullModel.from_values(keys, values)


def _shift(twin, effect, replicas, half, n_seeds) -> dict:
    """:func:`~imucal.gap.attribution.statistic_shift` of ``effect`` on ``half`` over the first
    ``n_seeds`` static replicas."""
    return statistic_shift(
        (static_statistics(render_static(twin, rep.seed, (effect,)), half), rep.stats[half])
        for rep in replicas[:n_seeds]
    )


def _locations(keys, t, reject, only_significant: bool) -> list[dict]:
    out = [
        {**dict(zip(LOCATION_FIELDS, k, strict=True)), "z": float(z), "in_gap": bool(r)}
        for k, z, r in zip(keys, t, reject, strict=True)
        if np.isfinite(z) and (r or not only_significant)
    ]
    return sorted(out, key=lambda d: -abs(d["z"]))


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
    replicas: int = 20,
    alpha: float = 0.05,
    seed: int = 1000,
    min_heldout_shrink: float = 0.3,
    crn_seeds: int = 3,
    detect_z: float = 4.0,
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
    replicas : int
        Twin replicas in the null (>= 5).
    alpha : float
        Family-wise level of the location test (Holm).
    seed : int
        First replica seed.
    min_heldout_shrink : float
        Smallest held-out shrink for an effect to be accepted.
    crn_seeds : int
        Replica seeds an effect is rendered with to measure its shift.
    detect_z : float
        Smallest |score| of an effect's estimate against the null for it to be evaluated.

    Returns
    -------
    dict
        diagnosis.json (the keys of the full diagnosis) plus ``scope``, ``not_observable``, ``twin``,
        ``null``, ``all_locations``, ``confusable``, ``settings``, ``timing_s``.

    Raises
    ------
    ValueError
        If fewer than 5 replicas are asked for or the recording has no stream of 100 rows.
    """
    if replicas < 5:
        raise ValueError(f"the null needs at least 5 replicas for a spread, got {replicas}")
    t0 = time.perf_counter()
    streams = split_streams(table)
    if not streams:
        raise ValueError(
            "the static recording has no acc/gyro or magnetometer stream of >= 100 rows"
        )
    stats = {h: static_statistics(streams, h) for h in HALVES}
    twin = build_static_twin(streams, calibration, dict(sensitivity or {}), gravity_m_s2)
    reps = [run_static_replica(twin, seed + i) for i in range(replicas)]
    t_null = time.perf_counter()
    keys = sorted(set.intersection(*(set(r.stats[None]) for r in reps)) & set(stats[None]), key=str)
    keys_b = sorted(set.intersection(*(set(r.stats["B"]) for r in reps)) & set(stats["B"]), key=str)
    null_full, null_b = _null(reps, None, keys), _null(reps, "B", keys_b)
    t_real = null_full.t(stats[None])
    reject = holm(null_full.p_values(t_real), alpha)
    loo = null_full.leave_one_out_gaps()

    cands = []
    for name, model in STATIC_LIBRARY.items():
        est, est_a = (
            model.estimate(streams),
            model.estimate({k: s.half("A") for k, s in streams.items()}),
        )
        if est is None:
            cands.append(Candidate(name, None, None, float("nan"), float("nan"),
                                   note="the session cannot show this effect (no such stream or channel)"))  # fmt: skip
            continue
        z = detection_z(
            est[1], [e[1] for e in (model.estimate(r.streams) for r in reps) if e is not None]
        )
        cands.append(Candidate(name, est[0], (est_a or est)[0], float(est[1]), z))

    def shifts_of(c: Candidate) -> tuple[dict, dict]:
        return (_shift(twin, make_effect(c.name, **c.params), reps, None, crn_seeds),
                _shift(twin, make_effect(c.name, **c.params_a), reps, "B", crn_seeds))  # fmt: skip

    explained, shift, _, rounds = select_forward(
        cands, stats, null_full, null_b, shifts_of,
        alpha=alpha, min_heldout_shrink=min_heldout_shrink, detect_z=detect_z,
    )  # fmt: skip

    t_after = null_full.t(stats[None], shift)
    reject_after = holm(null_full.p_values(t_after), alpha)
    effects = []

    def order(c):
        shrink = c.heldout_shrink if c.heldout_shrink is not None else -np.inf
        return (not c.accepted, -shrink)

    for c in sorted(cands, key=order):
        effects.append({
            "name": c.name, "params": c.params, "gap_before": c.gap_before,
            "gap_after": c.gap_after, "shrink": c.shrink, "heldout_shrink": c.heldout_shrink,
            "heldout_deviance": c.heldout_deviance, "accepted": c.accepted,
            "detect": None if c.params is None else c.detect,
            "detect_z": None if c.params is None else c.detect_z, "evaluated": c.evaluated,
            "signature_hits": [
                dict(zip(LOCATION_FIELDS, k, strict=True))
                for k, r in zip(keys, reject, strict=True) if r and STATIC_LIBRARY[c.name].matches(k)
            ],
            "note": c.note,
        })  # fmt: skip
    return {
        "format_version": FORMAT_VERSION,
        "dataset": dataset,
        "gap": {
            "total": null_full.gap(stats[None]),
            "null_p95": float(np.percentile(loo, 95)),
            "significant": bool(reject.any()),
        },  # fmt: skip
        "locations": _locations(keys, t_real, reject, True),
        "effects": effects,
        "explained": explained,
        "remaining": {
            "total": null_full.gap(stats[None], shift),
            "significant": bool(reject_after.any()),
            "locations": _locations(keys, t_after, reject_after, True),
        },
        "scope": "static",
        "not_observable": dict(NOT_OBSERVABLE),
        "confusable": confusable(rounds, explained, min_heldout_shrink),
        "all_locations": _locations(keys, t_real, reject, False),
        "null": {
            "replicas": replicas,
            "alpha": alpha,
            "n_locations": len(keys),
            "loo_gap_median": float(np.median(loo)),
            "loo_false_alarm": float(np.mean(null_full.leave_one_out_flags(alpha))),
        },  # fmt: skip
        "twin": twin.describe(),
        "settings": {
            "seed": seed,
            "min_heldout_shrink": min_heldout_shrink,
            "crn_seeds": crn_seeds,
            "detect_z": detect_z,
        },  # fmt: skip
        "timing_s": {"null": t_null - t0, "total": time.perf_counter() - t0},
    }


def diagnose_partial_session(
    static: pd.DataFrame | None,
    *,
    dataset: str,
    calibration: Mapping | None,
    sensitivity: Mapping[str, float],
    gravity_m_s2: float,
    replicas: int,
    alpha: float,
    seed: int,
    min_heldout_shrink: float,
    crn_seeds: int,
    detect_z: float,
) -> dict:
    """The gap diagnosis of a partial session: its static recording, or why none is scored.

    Parameters
    ----------
    static : DataFrame or None
        The ingested ``static`` recording, None when the session has none.
    dataset : str
    calibration, sensitivity, gravity_m_s2, replicas, alpha, seed, min_heldout_shrink, \
    crn_seeds, detect_z
        As in :func:`diagnose_static`.

    Returns
    -------
    dict
        :func:`diagnose_static`'s result, or :func:`unscored_diagnosis` with the reason.
    """
    if static is None:
        return unscored_diagnosis(
            dataset,
            "the session has no static recording; the twin of a partial session is rendered "
            "for a static recording only (its other recordings are hand-held motions the "
            "simulator's protocol does not describe)",
        )
    if not split_streams(static):
        return unscored_diagnosis(dataset, "the static recording has no stream of >= 100 samples")
    return diagnose_static(
        static, dataset=dataset, calibration=calibration, sensitivity=sensitivity,
        gravity_m_s2=gravity_m_s2, replicas=replicas, alpha=alpha, seed=seed,
        min_heldout_shrink=min_heldout_shrink, crn_seeds=crn_seeds, detect_z=detect_z,
    )  # fmt: skip
