"""The twin of a recording with an orientation reference: its motion replayed and rendered.

The twin (:class:`MotionTwin`) renders the recording's own motion: the calibrated gyroscope's
rates in B are the true body rate and are integrated from the reference's first present
orientation, so the true orientation and rate agree exactly; the session's calibration is the
truth, with the session's own noise per axis (:func:`session_noise`: white noise at the
recording's rests, else on the whole recording, robustly, with the rounding taken out; bias
instability and bias random walk from the Allan deviation of the longest rest; readings rounded
to the quantisation step); the accelerometer, when the recording has one, reads gravity at the
true orientation with the session's noise and rounding (the hand's linear acceleration is not
replayed: the knocks' statistic reads the accelerometer against its own neighbourhood);
the reference is rendered from the true orientation at the recorded reference times through the
measured clock and mounting, with white orientation noise from its third differences and the
recorded gaps. A replica is measured with the clock and mounting the recording was measured with
(both exact in the twin, so re-estimating them would only add their own small estimation noise)
and is not refitted.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation

from imucal import errormodel
from imucal.calibration import ImuCalibration, SensorCalibration
from imucal.columns import ACC, GYR, MAG, POSITION, QUAT, SENSORS, TIME
from imucal.gap.disturbance import SHOCK_ACC_SEPARATION_S, acc_spikes
from imucal.gap.motionstats import (
    MIN_INTERVALS,
    WINDOWS_S,
    MotionRecording,
    interval_residuals,
    motion_statistics,
)
from imucal.gap.statictwin import identity_calibration, quantum
from imucal.gap.statistics import HALVES
from imucal.gap.twin import Replica
from imucal.gap.worldfield import twin_world_turn
from imucal.noise.process import NoiseProcess, dither_std, fit_noise_process, white_process
from imucal.orientation import (
    integrate_rates,
    interpolate_orientation,
    quat_conjugate,
    quat_multiply,
)
from imucal.sim import World
from imucal.sim.effects import RecordingContext, stream_rng
from imucal.sim.motion import KinematicState
from imucal.sim.sensors import INT16_MAX, quantise, sensor_readings, true_signals
from imucal.sim.truth import REFERENCE_NOISE, Truth
from imucal.validation.orientation import (
    OrientationAlignment,
    align_orientation_reference,
    field_direction_errors,
)

#: Seed of the replica that measures the gyroscope's share of the residual (not a null seed).
NOISE_SEED = 2**31 - 1

# --------------------------------------------------------------------------- the recording


def _runs(mask: np.ndarray) -> list[slice]:
    """Contiguous runs of True in a boolean mask, as slices."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    return [slice(a, b) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def session_noise(parts: Sequence[tuple], step: float) -> NoiseProcess:
    """The noise process of one sensor from the rests of the recordings with a reference.

    Parameters
    ----------
    parts : sequence of (ndarray, ndarray or None, float)
        Per recording: the readings, shape (n, 3) (SI, finite), the mask of its samples at
        rest (shape (n,), or None) and its sample rate (Hz).
    step : float
        Quantisation step (SI per count).

    Returns
    -------
    NoiseProcess
        White noise per axis from first differences within the rests when they hold at least
        100 samples (else robustly, by the MAD of the first differences, over the whole
        recordings, where the motion inflates it a little), the rounding taken out; bias
        instability and bias random walk from the Allan deviation of the longest rest when
        it holds :data:`~imucal.noise.process.MIN_FIT_SAMPLES` samples.
    """
    rests = [
        (v[run], rate)
        for v, mask, rate in parts
        if mask is not None
        for run in _runs(mask)
        if run.stop - run.start >= 2
    ]
    if sum(len(r) for r, _ in rests) >= 100:
        longest, rate = max(rests, key=lambda r: len(r[0]))
        return fit_noise_process(longest, rate, step, [r for r, _ in rests])
    d = np.vstack([np.diff(v, axis=0) for v, _, _ in parts])
    mad = np.median(np.abs(d - np.median(d, axis=0)), axis=0)
    white = np.array([dither_std((1.4826 * m) ** 2 / 2.0, step) for m in mad])
    zero = np.zeros(3)
    return NoiseProcess(white, zero, np.ones(3), zero.copy(), float(step))


def _without_spikes(rec: MotionRecording, rest: np.ndarray | None) -> np.ndarray | None:
    """The rest mask less the samples within :data:`SHOCK_ACC_SEPARATION_S` of an
    accelerometer spike (:func:`acc_spikes`): a knock at rest is not the sensor's noise (its
    few samples of tens of m/s^2 would dominate the variance of the first differences)."""
    if rest is None:
        return None
    keep = rest.copy()
    for t0 in acc_spikes(rec)[0]:
        keep &= np.abs(rec.t_s - t0) > SHOCK_ACC_SEPARATION_S
    return keep


def slow_residual_variance(rec: MotionRecording) -> tuple[float, float]:
    """Residual variance of the gyroscope against the reference where it turns slowest.

    Over the quarter of the reference's intervals with the smallest gyroscope rate (rests
    included), the robust (MAD) variance of the residual pooled over the axes: there the errors
    that grow with the rate are small and the two sensors' noises remain.

    Returns
    -------
    variance : float
        (rad/s)^2.
    interval_s : float
        The median interval, s.
    """
    gyro, rate, _, duration = interval_residuals(rec, 9.81)
    speed = np.linalg.norm(gyro, axis=1)
    slow = speed <= np.percentile(speed, 25)
    res = (gyro - rate)[slow]
    mad = np.median(np.abs(res - np.median(res, axis=0)), axis=0)
    return float(np.mean((1.4826 * mad) ** 2)), float(np.median(duration))


@dataclass(frozen=True)
class _Recording:
    """What a replica of one recording is rendered from (see :class:`MotionTwin`)."""

    t_s: np.ndarray
    omega_b: np.ndarray
    start: np.ndarray
    t_reference: np.ndarray
    gaps: np.ndarray
    alignment: OrientationAlignment
    reference_noise_rad: float
    has_mag: bool
    has_acc: bool = False
    position: np.ndarray | None = None
    pos_reference: np.ndarray | None = None


@dataclass(frozen=True)
class MotionTwin:
    """Everything a replica of the recordings with an orientation reference is rendered from.

    Attributes
    ----------
    truth : Truth
        The session's calibration (identity for a sensor it does not calibrate); white noise
        pooled over the axes (for the effects that read it).
    sensitivity : dict
        Sensor -> quantisation step (SI per count): the readings are rounded to it, and it
        sets the full scale of ``scale_nonlinearity``.
    recordings : dict
        Name -> what its replica is rendered from.
    windows_s : tuple of float
    notes : list of str
    noise : dict
        Sensor -> :class:`~imucal.noise.process.NoiseProcess`, the session's noise (drawn
        instead of the truth's white noise, which a sensor without one gets; only the
        sensors with one are rounded).
    """

    truth: Truth
    sensitivity: dict
    recordings: dict
    windows_s: tuple = WINDOWS_S
    notes: list = field(default_factory=list)
    noise: dict = field(default_factory=dict)

    @property
    def gyr_full_scale_rad_s(self) -> float:
        """The gyroscope's full scale (rad/s): int16 counts of its quantisation step."""
        return INT16_MAX * self.sensitivity["gyr"]

    def describe(self) -> dict:
        """JSON-ready summary."""
        return {
            "noise": {k: float(v) for k, v in self.truth.noise.items()},
            "noise_process": {k: p.describe() for k, p in self.noise.items()},
            "reference_noise_rad": {k: r.reference_noise_rad for k, r in self.recordings.items()},
            "recordings": {
                k: {
                    "samples": int(len(r.t_s)),
                    "reference_samples": int(len(r.t_reference)),
                    "gap_samples": int(np.count_nonzero(r.gaps)),
                    "offset_s": r.alignment.time.offset_s,
                    "mounting_deg": r.alignment.mounting.angle_deg,
                }
                for k, r in self.recordings.items()
            },
            "windows_s": list(self.windows_s),
            "notes": list(self.notes),
        }

    def replica(self, seed: int, effects: tuple = (), halves: tuple = HALVES) -> Replica:
        """Render one replica of every recording (with optional simulator effects) and measure
        its statistics on the given ``halves``."""
        recordings = render_motion(self, seed, effects)
        g = self.truth.world.gravity_m_s2
        stats = {
            h: motion_statistics(recordings, h, windows_s=self.windows_s, gravity_m_s2=g)
            for h in halves
        }
        return Replica(seed, recordings, stats)


def recorded_motion(
    tables: Mapping[str, pd.DataFrame],
    references: Mapping[str, tuple[pd.DataFrame, Mapping]],
    calibration: Mapping | None,
    where: Mapping[str, str],
) -> dict[str, MotionRecording]:
    """The recordings with an orientation reference, calibrated and aligned.

    Parameters
    ----------
    tables : mapping of str to DataFrame
        Ingested recordings by name.
    references : mapping of str to (DataFrame, dict)
        Ingested orientation reference and its metadata (``up``) per recording.
    calibration : dict or None
        The session's calibration JSON; a gyroscope it does not calibrate is taken as read.
    where : mapping of str to str
        Per recording, the key path of its reference in ``dataset.yaml`` (error messages).

    Returns
    -------
    dict of str to MotionRecording
    """
    cals = _calibrations(calibration)
    out = {}
    for name, (reference, meta) in references.items():
        table = tables[name]
        values = table[list(GYR)].to_numpy(dtype=float)
        ok = np.all(np.isfinite(values), axis=1)
        t = table[TIME].to_numpy(dtype=float)[ok]
        gyr = errormodel.apply(cals["gyr"].matrix, cals["gyr"].bias, values[ok])
        mag = None
        if "mag" in (calibration or {}) and set(MAG) <= set(table.columns):
            # the magnetometer's own rows (a stream of its own in some loggers), at the
            # gyroscope's times
            raw = table[list(MAG)].to_numpy(dtype=float)
            fresh = np.all(np.isfinite(raw), axis=1)
            if np.count_nonzero(fresh) >= MIN_INTERVALS:
                t_mag = table[TIME].to_numpy(dtype=float)[fresh]
                at_gyr = np.column_stack([np.interp(t, t_mag, raw[fresh][:, k]) for k in range(3)])
                mag = errormodel.apply(cals["mag"].matrix, cals["mag"].bias, at_gyr)
        acc = None
        if set(ACC) <= set(table.columns):
            raw = table[list(ACC)].to_numpy(dtype=float)[ok]
            if np.all(np.isfinite(raw)):  # the accelerometer's rows are the gyroscope's
                acc = errormodel.apply(cals["acc"].matrix, cals["acc"].bias, raw)
        t_ref = reference[TIME].to_numpy(dtype=float)
        quat = reference[list(QUAT)].to_numpy(dtype=float)
        alignment = align_orientation_reference(t, gyr, t_ref, quat, where=where[name])
        pos = None
        if set(POSITION) <= set(reference.columns):
            pos = reference[list(POSITION)].to_numpy(dtype=float)
        out[name] = MotionRecording(t, gyr, mag, t_ref, quat, alignment, meta["up"], acc, pos)
    return out


def _calibrations(calibration: Mapping | None) -> dict[str, SensorCalibration]:
    out = {}
    for s in SENSORS:
        entry = (calibration or {}).get(s)
        if isinstance(entry, dict) and "matrix" in entry:
            out[s] = SensorCalibration.from_dict(s, entry)
        else:
            out[s] = identity_calibration(s)
    return out


def build_motion_twin(
    recordings: Mapping[str, MotionRecording],
    tables: Mapping[str, pd.DataFrame],
    calibration: Mapping | None,
    rests: Mapping[str, np.ndarray],
    sensitivity: Mapping[str, float],
    gravity_m_s2: float,
    windows_s: Sequence[float] = WINDOWS_S,
) -> MotionTwin:
    """The twin of the recordings with an orientation reference (module docstring).

    Parameters
    ----------
    recordings : dict of str to MotionRecording
        As :func:`recorded_motion` returns them.
    tables : mapping of str to DataFrame
        The ingested recordings (raw readings, for the noise).
    calibration : dict or None
    rests : mapping of str to ndarray of bool
        Per recording, the module samples (of ``MotionRecording.t_s``) at rest.
    sensitivity : mapping of str to float
        SI per count from dataset.yaml (estimated from the readings where absent).
    gravity_m_s2 : float
    windows_s : sequence of float

    Returns
    -------
    MotionTwin
    """
    cals = _calibrations(calibration)
    notes = [f"{s}: the session's calibration ({cals[s].method})" for s in SENSORS]
    noise, sens, spec, processes = {}, {}, {}, {}
    raw = {s: [] for s in ("gyr", "mag", "acc")}
    for name, rec in recordings.items():
        table = tables[name]
        values = table[list(GYR)].to_numpy(dtype=float)
        ok = np.all(np.isfinite(values), axis=1)
        rate = (len(rec.t_s) - 1) / (rec.t_s[-1] - rec.t_s[0])
        raw["gyr"].append((values[ok], rests.get(name), rate))
        if rec.acc is not None:  # the knocks' statistic reads it (imucal.gap.disturbance)
            values = table[list(ACC)].to_numpy(dtype=float)[ok]
            raw["acc"].append((values, _without_spikes(rec, rests.get(name)), rate))
        if rec.mag is not None:
            mag = table[list(MAG)].to_numpy(dtype=float)[ok]
            fresh = np.all(np.isfinite(mag), axis=1)
            keep = None if rests.get(name) is None else rests[name][fresh]
            raw["mag"].append((mag[fresh], keep, rate))
    for s, parts in raw.items():
        if parts:
            joined = np.vstack([v for v, _, _ in parts])
            sens[s] = float(sensitivity.get(s) or quantum(joined))
            processes[s] = session_noise(parts, sens[s])
            noise[s] = float(np.sqrt(np.mean(processes[s].white ** 2)))
    notes.append(
        "noise: the session's own per axis: white from first differences at the rests "
        "(segments static/position), else robustly over the whole recording, the rounding "
        "taken out; bias instability and bias random walk where the Allan deviation of the "
        "longest rest resolves them; readings rounded to the quantisation step"
    )
    for s in SENSORS:
        noise.setdefault(s, 0.0)
        sens.setdefault(s, float(sensitivity.get(s) or 1e-3))
    for name, rec in recordings.items():
        present = np.all(np.isfinite(rec.quat), axis=1)
        first = int(np.argmax(present))
        # B -> world of the first present reference sample, the true rate integrated from it
        tau = rec.alignment.to_module_time(rec.t_reference[first])
        q_body = rec.quat[first]
        q_mount = Rotation.from_matrix(rec.alignment.mounting.matrix)
        start = Rotation.from_quat(q_body[[1, 2, 3, 0]]) * q_mount.inv()
        # the world of the twin has +z up and magnetic north +x (the simulator's): carry the
        # reference's up and the recording's north there
        turn = twin_world_turn(rec)
        start = turn * start
        position = pos_reference = None
        if rec.pos is not None:
            # the position in the twin's world, at the reference's samples and (interpolated
            # over its gaps) at the module's
            pos_reference = turn.apply(np.nan_to_num(rec.pos))
            pos_reference[~np.isfinite(rec.pos).all(axis=1)] = np.nan
            known = np.isfinite(pos_reference).all(axis=1)
            tau_p = rec.alignment.to_module_time(rec.t_reference[known])
            position = np.column_stack(
                [np.interp(rec.t_s, tau_p, pos_reference[known, k]) for k in range(3)]
            )
        spec[name] = _Recording(
            t_s=rec.t_s,
            omega_b=rec.gyr,
            start=np.array([tau, *start.as_quat()[[3, 0, 1, 2]]]),
            t_reference=rec.t_reference,
            gaps=~present,
            alignment=rec.alignment,
            reference_noise_rad=0.0,
            has_mag=rec.mag is not None,
            has_acc=rec.acc is not None,
            position=position,
            pos_reference=pos_reference,
        )
    truth = Truth(
        calibration=ImuCalibration(cals["acc"], cals["gyr"], cals["mag"]),
        world=World(gravity_m_s2=gravity_m_s2, dip_rad=_dip_rad(recordings)),
        noise=noise,
        reference_noise=dict(REFERENCE_NOISE),
        mounting_rotvec_rad=np.zeros(3),
        preset="twin",
    )
    quiet = MotionTwin(truth, sens, spec, tuple(float(w) for w in windows_s), notes, processes)
    # the reference's noise: what the recording's slowest intervals show beyond the
    # gyroscope's share, which a replica without reference noise measures
    replica = render_motion(quiet, NOISE_SEED)
    for name, rec in recordings.items():
        recorded, interval = slow_residual_variance(rec)
        gyro_part, _ = slow_residual_variance(replica[name])
        # white orientation noise sigma gives rates of variance 2 sigma^2 / dt^2 per axis
        sigma = interval * np.sqrt(max(recorded - gyro_part, 0.0) / 2.0)
        spec[name] = dataclasses.replace(spec[name], reference_noise_rad=float(sigma))
    notes.append(
        "reference noise: white orientation noise matching the residual against the gyroscope "
        "over the slowest quarter of the intervals, beyond the gyroscope's share"
    )
    notes.append("clock and mounting: those measured on the recording; no refit")
    return dataclasses.replace(quiet, recordings=spec)


def _dip_rad(recordings: Mapping[str, MotionRecording]) -> float:
    dips = []
    for rec in recordings.values():
        if rec.mag is not None:
            found = field_direction_errors(
                rec.t_s, rec.mag, rec.t_reference, rec.quat, rec.alignment,
                rec.alignment.mounting.matrix, rec.up,
            )  # fmt: skip
            if found["dip_deg"] is not None:
                dips.append(np.radians(found["dip_deg"]))
    return float(np.mean(dips)) if dips else World().dip_rad


def render_motion(twin: MotionTwin, seed: int, effects: tuple = ()) -> dict[str, MotionRecording]:
    """One replica of every recording with a reference (see :class:`MotionTwin`).

    Sensor readings go through :mod:`imucal.sim` (true signals of the rendered orientation,
    white noise, the effects' ``on_truth``, ``on_true_signals`` and ``on_readings`` hooks);
    the gyroscope and magnetometer are then calibrated with the truth's calibration, as the
    recording was with the session's.
    """
    truth = twin.truth
    for effect in effects:
        truth = effect.on_truth(truth)
    cal = truth.calibration
    out = {}
    for name, r in twin.recordings.items():
        # true orientation B -> twin world at the module samples, from the first reference one
        q_rel = integrate_rates(r.t_s, r.omega_b)
        q_tau = interpolate_orientation(r.t_s, q_rel, np.array([r.start[0]]))[0]
        q_b = quat_multiply(quat_multiply(r.start[1:], quat_conjugate(q_tau)), q_rel)
        rotation = Rotation.from_quat(q_b[:, [1, 2, 3, 0]])
        state = KinematicState(r.t_s, rotation, r.omega_b, np.zeros_like(r.omega_b), r.position)
        rate_hz = (len(r.t_s) - 1) / (r.t_s[-1] - r.t_s[0])
        ctx = RecordingContext(name, rate_hz, 0.0, twin.sensitivity, seed, None, cal, {})
        true = true_signals(state, truth.world)
        for effect in effects:
            true = effect.on_true_signals(true, state, ctx)
        rng = stream_rng(seed, f"noise/{name}")
        # the session's noise per axis, drawn below, instead of the truth's white noise
        readings = sensor_readings(cal, true, dict.fromkeys(SENSORS, 0.0), rng)
        for s in SENSORS:
            process = twin.noise.get(s) or white_process(truth.noise[s], twin.sensitivity[s])
            drawn = process.draw(len(r.t_s), rate_hz, rng)
            readings = readings.with_sensor(s, readings.sensor(s) + drawn)
        for effect in effects:
            readings = effect.on_readings(readings, true, state, ctx)
        for s in twin.noise:
            counts, _ = quantise(readings.sensor(s), twin.sensitivity[s])
            readings = readings.with_sensor(s, counts * twin.sensitivity[s])
        gyr = errormodel.apply(cal.gyr.matrix, cal.gyr.bias, readings.gyr)
        mag = errormodel.apply(cal.mag.matrix, cal.mag.bias, readings.mag) if r.has_mag else None
        acc = errormodel.apply(cal.acc.matrix, cal.acc.bias, readings.acc) if r.has_acc else None
        # the reference: body -> world = (B -> world) M, at the instants its samples are
        # taken (the effects' on_reference_times), with its noise
        taken = r.t_reference
        for effect in effects:
            taken = effect.on_reference_times(
                taken, stream_rng(seed, f"{effect.name}/reference/{name}")
            )
        tau = r.alignment.to_module_time(taken)
        q_ref = quat_multiply(
            interpolate_orientation(r.t_s, q_b, tau),
            Rotation.from_matrix(r.alignment.mounting.matrix).as_quat()[[3, 0, 1, 2]],
        )
        rng = stream_rng(seed, f"reference/{name}")
        jitter = Rotation.from_rotvec(rng.normal(0.0, r.reference_noise_rad, (len(tau), 3)))
        q_ref = quat_multiply(q_ref, jitter.as_quat()[:, [3, 0, 1, 2]])
        q_ref[r.gaps] = np.nan
        out[name] = MotionRecording(
            r.t_s, gyr, mag, r.t_reference, q_ref, r.alignment, "+z", acc, r.pos_reference,
            twin.gyr_full_scale_rad_s,
        )  # fmt: skip
    return out
