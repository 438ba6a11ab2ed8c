"""The twin of a static recording and its rendering (full-rate tables or block means).

**StaticTwin** (a partial session's ``static`` recording, :mod:`imucal.gap.static`): the
simulator's ``static`` plan (a ``hold``), the sensor model, quantisation and the effects' hooks,
configured with the session's fitted calibration (identity for a sensor the session could not
calibrate: static statistics are about noise and drift, not about the mean), the session's own
noise (:func:`imucal.noise.process.fit_noise_process` on each stream: white noise per axis with
the quantisation taken out, bias instability and bias random walk from the IEEE 952 fit of its
Allan deviation after the readings' line on the temperature channel is taken out, rounded to
the recording's quantisation step), and the session's own timing:
the number of samples and effective rate ``(n - 1) / duration`` of the acc/gyro stream and of
the magnetometer stream, and its temperature channel carried over by time. No effect beyond the
paper's model and the session's noise: regular sample times, no loss, no temperature drift.

Its replicas are :class:`imucal.gap.twin.Replica`, measured as the full-protocol twin's are.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np

from imucal import errormodel
from imucal.calibration import ImuCalibration, SensorCalibration
from imucal.columns import SENSORS
from imucal.gap.statistics import HALVES
from imucal.gap.streams import STREAMS, Stream, static_statistics
from imucal.gap.twin import INT16_HEADROOM, Replica
from imucal.noise.process import fit_noise_process, white_process
from imucal.sim import ProtocolConfig, World
from imucal.sim.effects import RecordingContext, stream_rng
from imucal.sim.motion import evaluate_motion
from imucal.sim.packets import build_packet_log
from imucal.sim.protocol import plan_static
from imucal.sim.sensors import Signals, quantise, sensor_readings, true_signals
from imucal.sim.truth import REFERENCE_NOISE, Truth


@dataclass(frozen=True)
class StaticTwin:
    """Everything a replica of a static recording is rendered from.

    Attributes
    ----------
    truth : Truth
        Calibration = the session's (identity where it has none); white noise per sensor
        (pooled over the axes, for the effects that read it).
    sensitivity : dict
        Sensor -> quantisation step (SI per count), from dataset.yaml or the data.
    noise : dict
        Sensor -> :class:`~imucal.noise.process.NoiseProcess`, the session's noise (the
        replicas draw it; a sensor without one gets the truth's white noise).
    level : dict
        Sensor -> the recording's mean reading, shape (3,) (SI): the replicas' noise-free
        reading, so that a noise below one count flips the counts as often as in the
        recording (a sensor without one reads the hold through the calibration).
    streams : dict
        Stream name -> (number of samples, effective rate in Hz).
    temperature : tuple of ndarray or None
        (time since the first sample (s), temperature (deg C)) of the acc/gyro stream, carried
        over to the replicas by time.
    notes : list of str
    temperature_streams : tuple of str
        The streams whose rows carry the temperature channel in the recording (the replicas'
        carry it too).
    """

    truth: Truth
    sensitivity: dict
    streams: dict
    temperature: tuple | None = None
    notes: list = field(default_factory=list)
    noise: dict = field(default_factory=dict)
    level: dict = field(default_factory=dict)
    temperature_streams: tuple = ("imu",)

    @property
    def duration_s(self) -> float:
        return max((n - 1) / rate for n, rate in self.streams.values())

    def describe(self) -> dict:
        """JSON-ready summary."""
        return {
            "noise": {k: float(v) for k, v in self.truth.noise.items()},
            "noise_process": {k: p.describe() for k, p in self.noise.items()},
            "sensitivity": {k: float(v) for k, v in self.sensitivity.items()},
            "streams": {
                k: {"samples": int(n), "rate_hz": float(r)} for k, (n, r) in self.streams.items()
            },
            "duration_s": self.duration_s,
            "temperature_channel": self.temperature is not None,
            "notes": list(self.notes),
        }

    def replica(self, seed: int, effects: tuple = (), halves: tuple = HALVES) -> Replica:
        """Render one replica of the static recording (with optional simulator effects) and
        measure its statistics on the given ``halves``."""
        streams = render_static(self, seed, effects)
        return Replica(seed, streams, {h: static_statistics(streams, h) for h in halves})


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


def identity_calibration(sensor: str) -> SensorCalibration:
    """The calibration that leaves readings as they are (a sensor the session does not calibrate)."""
    unit = {"acc": "m/s^2", "gyr": "rad/s", "mag": "normalised"}[sensor]
    return SensorCalibration(sensor, np.zeros(3), np.eye(3), unit, method="identity (twin)")


def build_static_twin(
    streams: Mapping[str, Stream],
    calibration: Mapping | None,
    sensitivity: Mapping[str, float],
    gravity_m_s2: float,
    wander: bool = True,
) -> StaticTwin:
    """The twin of a static recording (see the module docstring).

    Parameters
    ----------
    streams : dict
        Output of :func:`imucal.gap.streams.split_streams`.
    calibration : dict or None
        The session's calibration JSON (``partial/calibration.json``): sensors it holds are
        used, the others are identity.
    sensitivity : dict
        SI per count from dataset.yaml (may be empty: then estimated from the readings).
    gravity_m_s2 : float
    wander : bool
        Whether the twin's noise holds the recording's own bias instability and random walk
        (a partial session: the sensor as it is) or only its white noise, as the full
        protocol's twin (:func:`imucal.gap.twin.build_twin`), for which a wandering bias is an
        effect (``bias_instability``): the static recording of a full-protocol session whose
        chain stopped is diagnosed so.

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
            cals[s] = identity_calibration(s)
    noise, sens, processes, level = {}, {}, {}, {}
    for name, stream in streams.items():
        for s, x in stream.values.items():
            q = float(sensitivity.get(s) or quantum(x))
            if not sensitivity.get(s):
                notes.append(f"{s}: quantisation step {q:.4g} SI estimated from the readings")
            level[s] = x.mean(axis=0)
            processes[s] = fit_noise_process(
                _untempered(x, stream.temperature_c), stream.rate_hz, q, level=level[s]
            )
            if not wander:
                zero = np.zeros(3)
                processes[s] = replace(processes[s], markov=zero, walk=zero.copy())
            noise[s], sens[s] = float(np.sqrt(np.mean(processes[s].white ** 2))), q
    missing = [s for s in SENSORS if s not in noise]
    for s in missing:  # not rendered into any stream; the simulator needs a value
        noise[s], sens[s] = 0.0, 1e-3
    notes.append(
        "noise: the session's own, per axis: white from first differences with the rounding "
        "taken out, bias instability and bias random walk where the IEEE 952 fit of the "
        "recording's Allan deviation resolves them"
        if wander
        else "noise: the session's white noise per axis, from first differences with the "
        "rounding taken out (a wandering bias is an effect, as in the full protocol's twin)"
    )
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
    carried = tuple(name for name, st in streams.items() if st.temperature_c is not None)
    return StaticTwin(truth, sens, spec, temp, notes, processes, level, carried)


def _untempered(x: np.ndarray, temperature_c: np.ndarray | None) -> np.ndarray:
    """Readings (n, 3) less their least-squares line on the temperature channel: the noise is
    measured on what the temperature does not explain, so that a drift with temperature stays
    a physical effect (``temperature_drift``) instead of entering the twin's noise."""
    if temperature_c is None:
        return x
    d_t = temperature_c - temperature_c.mean()
    if not d_t @ d_t > 0:
        return x
    return x - np.outer(d_t, d_t @ (x - x.mean(axis=0)) / (d_t @ d_t))


def _about_level(readings: Signals, plain: Mapping, level: Mapping) -> Signals:
    """Readings whose effects vary about the recording's level instead of moving it.

    The level is the recording's mean reading, which holds whatever its effects did over it:
    a bias drift with temperature, rendered from the effect's ``start_c``, is in it at the
    recording's mean temperature. So the mean over the stream of what the effects changed
    (``readings - plain``, per axis) is taken out of each sensor with a level; otherwise a
    drift's mean would count twice and move the replica off the recording's range, where it
    clips at the int16 full scale of its step and its statistics move with it.

    Parameters
    ----------
    readings : Signals
        The replica's readings with the effects (SI, before rounding).
    plain : dict
        Sensor -> the same readings without any effect, shape (n, 3) (SI).
    level : dict
        Sensor -> the recording's mean reading, shape (3,) (:attr:`StaticTwin.level`).

    Returns
    -------
    Signals
    """
    for s, x in plain.items():
        if s in level:
            moved = readings.sensor(s)
            readings = readings.with_sensor(s, moved - np.mean(moved - x, axis=0))
    return readings


def render_static(twin: StaticTwin, seed: int, effects: tuple = ()) -> dict[str, Stream]:
    """One replica of the static recording, as streams.

    The simulator's ``static`` plan (a ``hold``) is evaluated at each stream's sample times
    ``k / rate``; sensor readings, quantisation and packets go through :mod:`imucal.sim` with
    the effects' hooks (``on_truth``, ``on_true_signals``, ``on_readings``, ``on_packets``).
    Each stream is a recording of its own for the random streams (``static/imu``,
    ``static/mag``). A sensor with a level (:attr:`StaticTwin.level`) reads it on average,
    with or without effects: the effects vary about it (:func:`_about_level`).

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
        # the recording's own level: the hold's reading moved to it (before any effect)
        moved = {
            s: twin.level[s] - errormodel.invert(cal.matrix, cal.bias, true.sensor(s)[:1])[0]
            for s, cal in ((s, truth.calibration.sensor(s)) for s in twin.level)
        }
        hold = true
        for effect in effects:
            true = effect.on_true_signals(true, state, ctx)
        rng = stream_rng(seed, f"noise/{rec}")
        # the session's noise per axis, drawn below, instead of the truth's white noise
        readings = sensor_readings(truth.calibration, true, dict.fromkeys(SENSORS, 0.0), rng)
        plain = {}
        for s in STREAMS[name]:
            process = twin.noise.get(s) or white_process(truth.noise[s], twin.sensitivity[s])
            drawn = process.draw(n, rate, rng) + moved.get(s, 0.0)
            readings = readings.with_sensor(s, readings.sensor(s) + drawn)
            cal = truth.calibration.sensor(s)
            plain[s] = errormodel.invert(cal.matrix, cal.bias, hold.sensor(s)) + drawn
        for effect in effects:
            readings = effect.on_readings(readings, true, state, ctx)
        if effects:
            readings = _about_level(readings, plain, twin.level)
        counts = {s: quantise(readings.sensor(s), twin.sensitivity[s])[0] for s in SENSORS}
        log = build_packet_log(counts, 0, rate, mag_every=1)
        for effect in effects:
            log = effect.on_packets(log, ctx)
        values = {s: log.counts[s] * twin.sensitivity[s] for s in STREAMS[name]}
        temp = None
        if name in twin.temperature_streams:
            if "temp_c" in log.extra:
                temp = np.asarray(log.extra["temp_c"], dtype=float)
            elif twin.temperature is not None:
                temp = np.interp(log.sample / rate, *twin.temperature)
        out[name] = Stream(np.asarray(log.t_s, dtype=float), values, temp)
    return out
