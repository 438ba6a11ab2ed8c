"""The sim-to-real gap of recordings with an orientation reference (motion capture, robot).

A recording declared with an orientation reference shows what a static recording cannot: the
gyroscope over the rates and orientations the hand or the robot gave it, against an independent
measure of the same rotation. Its locations are stage ``reference`` x sensor x axis x segment
(the recording) x statistic:

* per gyroscope axis, over the reference's intervals (the calibrated gyroscope averaged over
  each interval against the reference's body rate carried into B by the mounting): the
  residual's ``resid_rms``; ``ref_scale``, the slope gyroscope per reference; ``rate2`` and
  ``rate3``, the residual's curvature in the rate (as for a rate table); ``ref_g_slope``, the
  residual per specific force along the axis (gravity from the reference's orientation);
* the orientation integrated from the gyroscope over windows against the reference's
  (:func:`imucal.validation.orientation.window_errors`), ``ori_median_rad`` per window length
  (segment ``{recording}/{T}s``);
* the magnetometer's field direction carried into the reference's world, ``dir_resid_rad``
  (median angle about its mean direction), when the session calibrates the magnetometer.

The twin (:class:`MotionTwin`) renders the recording's own motion: the calibrated gyroscope's
rates in B are the true body rate and are integrated from the reference's first present
orientation, so the true orientation and rate agree exactly; the session's calibration is the
truth, with the session's own noise per axis (:func:`session_noise`: white noise at the
recording's rests, else on the whole recording, robustly, with the rounding taken out; bias
instability and bias random walk from the Allan deviation of the longest rest; readings rounded
to the quantisation step);
the reference is rendered from the true orientation at the recorded reference times through the
measured clock and mounting, with white orientation noise from its third differences and the
recorded gaps. A replica is measured with the clock and mounting the recording was measured with
(both exact in the twin, so re-estimating them would only add their own small estimation noise)
and is not refitted.

The effects such a recording can show (:func:`motion_library`): ``g_sensitivity`` (a gyroscope
output following the specific force), ``scale_nonlinearity`` (a response curved in the rate,
which makes a scale fitted on fast motion wrong on slow motion) and ``reference_jitter`` (the
reference's samples taken off their time stamps: an error growing with the rate), and the
disturbances of hand-held and robot use with their own locations (:mod:`imucal.gap.disturbance`:
``world_magnetic``, ``shock``, ``vibration``).
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
from imucal.columns import AXES, GYR, MAG, QUAT, SENSORS, TIME
from imucal.gap.disturbance import (
    disturbance_statistics,
    estimate_shock,
    estimate_vibration,
    estimate_world_magnetic,
    twin_world_turn,
)
from imucal.gap.effects import EffectModel, Estimate
from imucal.gap.statictwin import identity_calibration, quantum
from imucal.gap.statistics import HALVES
from imucal.gap.twin import Replica
from imucal.noise.process import NoiseProcess, dither_std, fit_noise_process, white_process
from imucal.orientation import (
    integrate_rates,
    interpolate_orientation,
    interval_means,
    quat_conjugate,
    quat_multiply,
    quat_rotate,
    up_vector,
)
from imucal.segments.table import rows_of
from imucal.sim import World
from imucal.sim.effects import RecordingContext, stream_rng
from imucal.sim.motion import KinematicState
from imucal.sim.sensors import INT16_MAX, quantise, sensor_readings, true_signals
from imucal.sim.truth import REFERENCE_NOISE, Truth
from imucal.validation.orientation import (
    OrientationAlignment,
    align_orientation_reference,
    field_direction_errors,
    reference_rates,
    window_errors,
)

#: Effects of the simulator that recordings with an orientation reference do not show, and why.
MOTION_NOT_OBSERVABLE = {
    "timing_jitter": "no static recording: receive-time statistics need a long regular stream",
    "packet_loss": "no packet counter is compared: a lost sample and a late one look the same",
    "bias_instability": "no static recording: the Allan deviation needs a long rest",
    "temperature_drift": "no static recording with a temperature channel",
    "time_offset": "the clock against the reference is measured and removed (validation.json)",
    "mag_latency": "the twin renders the recorded motion, not a plan it could delay",
    "lever_arm": "the gyroscope, not the accelerometer, is compared with the reference",
    "earth_rotation": "below the resolution of an optical reference's rates",
    "saturation": "clipping shows in the readings themselves (ingest summary), not against a "
    "reference",
    "hand_tremor": "the twin replays the recorded motion, tremor included",
    "placement_error": "the mounting against the reference is measured per recording",
    "large_misalignment": "the mounting against the reference is measured per recording",
    "platform_magnetic": "no turntable in the recordings",
}
#: Window lengths of the orientation statistic (s), when the configuration gives none.
WINDOWS_S = (1.0, 10.0)
#: Seed of the replica that measures the gyroscope's share of the residual (not a null seed).
NOISE_SEED = 2**31 - 1
#: Fewest reference intervals per axis for the rate regressions of a half.
MIN_INTERVALS = 50


@dataclass(frozen=True)
class MotionRecording:
    """One recording with its orientation reference, as the statistics read it.

    Attributes
    ----------
    t_s : ndarray, shape (n,)
        Module times, s.
    gyr : ndarray, shape (n, 3)
        Calibrated gyroscope in B, rad/s.
    mag : ndarray, shape (n, 3), or None
        Calibrated magnetometer in B (normalised), None when the session does not calibrate it.
    t_reference : ndarray, shape (m,)
        Reference times on its own clock, s.
    quat : ndarray, shape (m, 4)
        Reference body -> world, scalar first; NaN rows in its gaps.
    alignment : OrientationAlignment
        Clock and mounting (reference body -> B).
    up : str
        The reference world's up axis (``+z``...).
    """

    t_s: np.ndarray
    gyr: np.ndarray
    mag: np.ndarray | None
    t_reference: np.ndarray
    quat: np.ndarray
    alignment: OrientationAlignment
    up: str

    def half(self, half: str | None) -> MotionRecording:
        """The first (A) or second (B) half in module time, or the whole (None)."""
        if half is None:
            return self
        mid = 0.5 * (self.t_s[0] + self.t_s[-1])
        keep = self.t_s <= mid if half == "A" else self.t_s > mid
        tau = self.alignment.to_module_time(self.t_reference)
        keep_r = tau <= mid if half == "A" else tau > mid
        return dataclasses.replace(
            self,
            t_s=self.t_s[keep],
            gyr=self.gyr[keep],
            mag=None if self.mag is None else self.mag[keep],
            t_reference=self.t_reference[keep_r],
            quat=self.quat[keep_r],
        )


def interval_residuals(rec: MotionRecording, gravity_m_s2: float) -> tuple:
    """The calibrated gyroscope against the mounted reference rate over the reference's intervals.

    Returns
    -------
    gyro : ndarray, shape (k, 3)
        Calibrated gyroscope averaged over each interval (B, rad/s).
    rate : ndarray, shape (k, 3)
        The reference's body rate carried into B, rad/s.
    force : ndarray, shape (k, 3)
        Specific force of gravity in B at the interval's start (m/s^2).
    duration : ndarray, shape (k,)
        The interval's length on the reference's clock, s.
    """
    start, end, body = reference_rates(rec.t_reference, rec.quat)
    to_module = rec.alignment.to_module_time
    gyro = interval_means(rec.t_s, rec.gyr, to_module(start), to_module(end))
    mounting = rec.alignment.mounting.matrix
    first = np.searchsorted(rec.t_reference, start)
    up_body = quat_rotate(quat_conjugate(rec.quat[first]), up_vector(rec.up))
    ok = np.all(np.isfinite(gyro), axis=1)
    return (
        gyro[ok],
        body[ok] @ mounting.T,
        gravity_m_s2 * up_body[ok] @ mounting.T,
        (end - start)[ok],
    )


def motion_statistics(
    recordings: Mapping[str, MotionRecording],
    half: str | None = None,
    *,
    windows_s: Sequence[float] = WINDOWS_S,
    gravity_m_s2: float = 9.81,
) -> dict:
    """Every location of the recordings with an orientation reference (module docstring).

    Parameters
    ----------
    recordings : dict of str to MotionRecording
    half : {None, 'A', 'B'}
    windows_s : sequence of float
        Window lengths of ``ori_median_rad``, s.
    gravity_m_s2 : float

    Returns
    -------
    dict
        ``(stage, sensor, axis, segment, statistic)`` -> value.
    """
    out = {}
    for name, whole in recordings.items():
        rec = whole.half(half)
        gyro, rate, force, _ = interval_residuals(rec, gravity_m_s2)
        if len(gyro) >= MIN_INTERVALS:
            res = gyro - rate
            for j, a in enumerate(AXES):
                key = ("reference", "gyr", a, name)
                out[(*key, "resid_rms")] = float(np.sqrt(np.mean(res[:, j] ** 2)))
                centred = gyro[:, j] - gyro[:, j].mean()
                out[(*key, "ref_scale")] = float(
                    np.sum(centred**2) / np.sum(centred * (rate[:, j] - rate[:, j].mean()))
                )
                w = rate[:, j]
                design = np.column_stack([np.ones_like(w), w, w**2, w**3, force[:, j]])
                c, *_ = np.linalg.lstsq(design, res[:, j], rcond=None)
                out[(*key, "rate2")] = float(c[2])
                out[(*key, "rate3")] = float(c[3])
                out[(*key, "ref_g_slope")] = float(c[4])
        errors = window_errors(
            rec.t_s, rec.gyr, rec.t_reference, rec.quat, rec.alignment,
            rec.alignment.mounting.matrix, windows_s,
        )  # fmt: skip
        for key, (_, err) in errors.items():
            if err.size >= 5:
                out[("reference", "gyr", "-", f"{name}/{key}", "ori_median_rad")] = float(
                    np.radians(np.median(err))
                )
        if rec.mag is not None:
            found = field_direction_errors(
                rec.t_s, rec.mag, rec.t_reference, rec.quat, rec.alignment,
                rec.alignment.mounting.matrix, rec.up,
            )  # fmt: skip
            if found["n"] >= MIN_INTERVALS:
                out[("reference", "mag", "-", name, "dir_resid_rad")] = float(
                    np.radians(found["median_deg"])
                )
        out.update(disturbance_statistics(name, rec))
    return out


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
        t_ref = reference[TIME].to_numpy(dtype=float)
        quat = reference[list(QUAT)].to_numpy(dtype=float)
        alignment = align_orientation_reference(t, gyr, t_ref, quat, where=where[name])
        out[name] = MotionRecording(t, gyr, mag, t_ref, quat, alignment, meta["up"])
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
    raw = {s: [] for s in ("gyr", "mag")}
    for name, rec in recordings.items():
        table = tables[name]
        values = table[list(GYR)].to_numpy(dtype=float)
        ok = np.all(np.isfinite(values), axis=1)
        rate = (len(rec.t_s) - 1) / (rec.t_s[-1] - rec.t_s[0])
        raw["gyr"].append((values[ok], rests.get(name), rate))
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
        start = twin_world_turn(rec) * start
        spec[name] = _Recording(
            t_s=rec.t_s,
            omega_b=rec.gyr,
            start=np.array([tau, *start.as_quat()[[3, 0, 1, 2]]]),
            t_reference=rec.t_reference,
            gaps=~present,
            alignment=rec.alignment,
            reference_noise_rad=0.0,
            has_mag=rec.mag is not None,
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
        state = KinematicState(r.t_s, rotation, r.omega_b, np.zeros_like(r.omega_b))
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
        out[name] = MotionRecording(r.t_s, gyr, mag, r.t_reference, q_ref, r.alignment, "+z")
    return out


# --------------------------------------------------------------------------- the effects


def _pooled(session: Mapping[str, MotionRecording], half, gravity_m_s2: float = 9.81):
    parts = [interval_residuals(rec.half(half), gravity_m_s2) for rec in session.values()]
    parts = [p for p in parts if len(p[0]) >= MIN_INTERVALS]
    if not parts:
        return None
    return tuple(np.concatenate([p[k] for p in parts]) for k in range(4))


def estimate_g_sensitivity(session: Mapping[str, MotionRecording], half) -> Estimate | None:
    """Gyroscope output per specific force, the full matrix ``G`` (rad/s per m/s^2, frame B:
    the model term's parameterisation): the residual against the reference, each axis
    regressed on the three components of the specific force with an offset."""
    found = _pooled(session, half)
    if found is None:
        return None
    gyro, rate, force, _ = found
    res = gyro - rate
    design = np.column_stack([np.ones(len(res)), force])
    if np.linalg.matrix_rank(design) < 4:
        return None
    g = np.linalg.lstsq(design, res, rcond=None)[0][1:].T
    return Estimate({"matrix": g.tolist()}, float(np.linalg.norm(g)))


def estimate_scale_nonlinearity(
    session: Mapping[str, MotionRecording], half, full_scale_rad_s: float
) -> Estimate | None:
    """A gyroscope response curved in the rate, common to the axes: the residual against the
    reference regressed on ``FS (k2 x^2 + k3 x^3)`` with ``x = rate / FS`` (an offset and a
    slope per axis: the calibration takes the linear part)."""
    found = _pooled(session, half)
    if found is None:
        return None
    gyro, rate, _, _ = found
    res = gyro - rate
    n = len(res)
    x = rate / full_scale_rad_s
    columns = []
    for j in range(3):
        block = np.zeros((n * 3, 2))
        block[j * n : (j + 1) * n, 0] = 1.0
        block[j * n : (j + 1) * n, 1] = rate[:, j]
        columns.append(block)
    curved = np.column_stack(
        [full_scale_rad_s * (x**2).T.ravel(), full_scale_rad_s * (x**3).T.ravel()]
    )
    design = np.hstack([*columns, curved])
    coef = np.linalg.lstsq(design, res.T.ravel(), rcond=None)[0]
    k2, k3 = float(coef[-2]), float(coef[-1])
    zero = {f"{s}_{k}": 0.0 for s in ("acc", "mag") for k in ("k2", "k3")}
    return Estimate({**zero, "gyr_k2": k2, "gyr_k3": k3}, abs(k2) + abs(k3))


def estimate_reference_jitter(session: Mapping[str, MotionRecording], half) -> Estimate | None:
    """White jitter of the reference's sampling instants: its rate over an interval ``dt``
    errs by ``omega (e_{k+1} - e_k) / dt``, so the squared residual against the gyroscope grows
    as ``2 std^2 omega_j^2 / dt^2`` on axis j above the noise floor; a least-squares fit of
    that line (an intercept per axis, one slope) gives ``std^2``."""
    found = _pooled(session, half)
    if found is None:
        return None
    gyro, rate, _, duration = found
    res = gyro - rate
    n = len(res)
    design = np.zeros((3 * n, 4))
    for j in range(3):
        design[j * n : (j + 1) * n, j] = 1.0
        design[j * n : (j + 1) * n, 3] = 2.0 * rate[:, j] ** 2 / duration**2
    coef = np.linalg.lstsq(design, (res**2).T.ravel(), rcond=None)[0]
    std = float(np.sqrt(max(coef[3], 0.0)))
    return Estimate({"std_s": std}, std)


def motion_library(twin: MotionTwin | None = None) -> dict[str, EffectModel]:
    """The effects recordings with an orientation reference can show (module docstring).

    Without a twin the models hold no session's full scale: the catalogue of effects
    (:mod:`imucal.gap.catalogue`) reads their names and signatures only.
    """
    full_scale = INT16_MAX * twin.sensitivity["gyr"] if twin is not None else float("nan")
    return {
        "g_sensitivity": EffectModel(
            "g_sensitivity",
            estimate_g_sensitivity,
            (("reference", "gyr", "ref_g_slope"), ("reference", "gyr", "resid_rms")),
            "gyroscope output following the specific force (gravity along each axis)",
        ),
        "scale_nonlinearity": EffectModel(
            "scale_nonlinearity",
            lambda session, half: estimate_scale_nonlinearity(session, half, full_scale),
            (
                ("reference", "gyr", "rate2"),
                ("reference", "gyr", "rate3"),
                ("reference", "gyr", "ref_scale"),
                ("reference", "gyr", "resid_rms"),
                ("reference", "gyr", "ori_median_rad"),
            ),
            "gyroscope response curved in the rate (a scale that depends on the rate)",
        ),
        "reference_jitter": EffectModel(
            "reference_jitter",
            estimate_reference_jitter,
            (("reference", "gyr", "resid_rms"), ("reference", "gyr", "ori_median_rad")),
            "the reference's samples taken off their time stamps (an error growing with rate)",
        ),
        "world_magnetic": EffectModel(
            "world_magnetic",
            estimate_world_magnetic,
            (("reference", "mag", "field_position_rms"), ("reference", "mag", "dir_resid_rad")),
            "a field fixed in the world near the path: the world field follows the sensor's "
            "position (linear in its attitude about a pivot), not its rate",
        ),
        "shock": EffectModel(
            "shock",
            estimate_shock,
            (("reference", "gyr", "shock_rate"), ("reference", "gyr", "resid_rms")),
            "knocks: gyroscope pulses of a few ms the reference does not follow",
        ),
        "vibration": EffectModel(
            "vibration",
            estimate_vibration,
            (("reference", "gyr", "line_power"), ("reference", "gyr", "resid_rms")),
            "a line in the gyroscope the reference does not follow (a machine, a robot's drives)",
        ),
    }


def motion_part(
    tables: Mapping[str, pd.DataFrame],
    references: Mapping[str, tuple[pd.DataFrame, Mapping]],
    calibration: Mapping | None,
    segments: pd.DataFrame,
    where: Mapping[str, str],
    sensitivity: Mapping[str, float],
    gravity_m_s2: float,
    windows_s: Sequence[float] = WINDOWS_S,
) -> tuple[dict[str, MotionRecording], MotionTwin]:
    """The recordings with an orientation reference and their twin, for the diagnosis.

    Parameters
    ----------
    tables, references, calibration, where
        As in :func:`recorded_motion`.
    segments : DataFrame
        The segments table; ``static`` and ``position`` segments are the rests (noise).
    sensitivity, gravity_m_s2, windows_s
        As in :func:`build_motion_twin`.

    Returns
    -------
    recordings : dict of str to MotionRecording
        The recordings whose reference could be aligned (the others are named in the twin's
        notes with the reason).
    twin : MotionTwin

    Raises
    ------
    ValueError
        When no recording's reference can be aligned (each reason in the message).
    """
    recordings, skipped = {}, []
    for name in references:
        try:
            recordings |= recorded_motion(tables, {name: references[name]}, calibration, where)
        except ValueError as err:  # a reference the gyroscope cannot be aligned with
            skipped.append(f"{name}: {err}")
    if not recordings:
        raise ValueError(
            "no recording's reference could be aligned with its gyroscope: " + "; ".join(skipped)
        )
    rests = {}
    for name, rec in recordings.items():
        rows = rows_of(segments, name, "static", "position")
        mask = np.zeros(len(rec.t_s), dtype=bool)
        for lo, hi in zip(rows["start_s"].astype(float), rows["end_s"].astype(float)):
            mask |= (rec.t_s >= lo) & (rec.t_s <= hi)
        rests[name] = mask
    twin = build_motion_twin(
        recordings, tables, calibration, rests, sensitivity, gravity_m_s2, windows_s
    )
    notes = [f"not scored, the reference could not be aligned: {why}" for why in skipped]
    return recordings, dataclasses.replace(twin, notes=[*twin.notes, *notes])


def reference_part(**inputs) -> tuple[tuple | None, str | None]:
    """:func:`motion_part` of the same keyword arguments, or why the recordings with a reference
    cannot be scored.

    Returns
    -------
    part : (dict of str to MotionRecording, MotionTwin) or None
    not_scored : str or None
        The reason when ``part`` is None (no reference could be aligned with its gyroscope).
    """
    try:
        return motion_part(**inputs), None
    except ValueError as err:
        return None, str(err)
