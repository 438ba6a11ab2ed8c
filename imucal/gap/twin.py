"""The twin of a recorded session: the simulator under the paper's error model, configured from
the session itself, and its replicas.

Two twins share one contract, :meth:`Twin.replica` / :meth:`~imucal.gap.statictwin.StaticTwin.replica`: render the
session again with a fresh seed (and optionally simulator effects) and measure the replica with
the same code as the session (:class:`Replica`), so the null (:mod:`imucal.gap.null`) and the
attribution (:mod:`imucal.gap.attribution`) work on either.

**Twin** (full protocol). It takes from the session only what the paper's model and the protocol describe: the
fitted calibration (as the truth), white-noise levels estimated from its static data, gravity
and the magnetic dip seen by its calibrated sensors, the reference mounting, the sensor
sensitivities, and the protocol's timing (segment durations, phase turns and rates, rate
table rates). It has no effect beyond the paper's model: no packet loss, exact timestamps, a
reference started with the module, and no sensor range (the paper's model has none: the twin's
ADC is the int16 full scale, :func:`replica_options`), so a session that clips opens a gap
that the saturation effect, at the clip level read from the session, explains. Replicas
differ only in their random seed.

The static twin of a partial session's ``static`` recording is in :mod:`imucal.gap.statictwin`;
the replica and the contract are defined here, once.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd
from scipy import stats
from scipy.spatial.transform import Rotation

from imucal.columns import SENSOR_COLUMNS, SENSORS, SEQ, TIME, temperature_column
from imucal.gap.blocks import COUNT_COLUMNS, STATIC_WINDOW_S, StaticBlocks
from imucal.gap.locations import stamp_resolution
from imucal.gap.statistics import HALVES, compute_statistics
from imucal.ingest import reference_to_table
from imucal.io.raw import MtManagerExport
from imucal.pipeline.full import PipelineOptions, SessionFit, calibrate_session, calibrated
from imucal.sim import SENSITIVITY, ProtocolConfig, World, plan_session, simulate_session
from imucal.sim.effects import RecordingContext, stream_rng
from imucal.sim.motion import evaluate_motion
from imucal.sim.sensors import INT16_MAX, sensor_readings, true_signals
from imucal.sim.session import REFERENCE_RATE_HZ
from imucal.sim.truth import REFERENCE_NOISE, Truth

#: Recordings the simulator renders, in protocol order.
TWIN_RECORDINGS = ("rotation3d", "cube", "ratetable", "static")


#: Smallest resolution of a synthetic quantiser: counts must fit the int16 range.
INT16_HEADROOM = 30000.0


@dataclass(frozen=True)
class Replica:
    """One twin replica, measured as the session is.

    Attributes
    ----------
    seed : int
    session : SessionFit or dict of str to Stream
        What the effect estimators read: the refitted session (:class:`Twin`) or the rendered
        streams (:class:`StaticTwin`).
    stats : dict
        Half (None, 'A', 'B') -> location -> value.
    """

    seed: int
    session: object
    stats: dict


@dataclass(frozen=True)
class Twin:
    """Everything a twin replica is rendered from.

    Attributes
    ----------
    truth : Truth
        Calibration = the session's fitted calibration; noise from its static data.
    config : ProtocolConfig
        Timing of the session's protocol.
    options : PipelineOptions
        Pipeline settings (and sensitivities, declared ranges) of the session; the replicas
        are fitted with :func:`replica_options`.
    recordings : tuple of str
        IMU recordings the session has (the twin renders the same).
    has_reference : bool
    extra_columns : dict
        Recording -> column -> (t_s (n,), values (n,)): extra columns of the session (e.g. a
        temperature channel), carried over to the replicas by recording time so that
        statistics against them have a null.
    notes : list of str
        How each ingredient was estimated.
    static_blocks : BlockSpec or None
        The block means of a long static recording (:mod:`imucal.gap.blocks`): the replica
        renders the recording's window at full rate (``config.static_s``) and its blocks with
        :func:`render_static_blocks`. None when the static recording is rendered whole.
    stamp_resolution_s : float
        Resolution of the session's timestamps (:func:`imucal.gap.locations.stamp_resolution`,
        0 for full float precision): a replica's timing statistics are floored at its rounding
        as the session's are (:func:`imucal.gap.locations.stamp_floor`).
    """

    truth: Truth
    config: ProtocolConfig
    options: PipelineOptions
    recordings: tuple
    has_reference: bool
    extra_columns: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)
    static_blocks: BlockSpec | None = None
    stamp_resolution_s: float = 0.0

    def describe(self) -> dict:
        """JSON-ready summary (noise, world, protocol timing)."""
        return {
            "noise": {k: float(v) for k, v in self.truth.noise.items()},
            "reference_noise": {k: float(v) for k, v in self.truth.reference_noise.items()},
            "gravity_m_s2": self.truth.world.gravity_m_s2,
            "dip_deg": float(np.degrees(self.truth.world.dip_rad)),
            "recordings": list(self.recordings),
            "range_counts": dict(replica_options(self).range_counts),
            "has_reference": self.has_reference,
            "static_blocks": self.static_blocks.describe() if self.static_blocks else None,
            "protocol": {
                k: (list(v) if isinstance(v, tuple) else v) for k, v in self.config.__dict__.items()
            },
            "notes": list(self.notes),
        }

    def replica(self, seed: int, effects: tuple = (), halves: tuple = HALVES) -> Replica:
        """Render, refit and measure one replica (with optional simulator effects), its
        statistics on the given ``halves``."""
        imu, reference = render_replica(self, seed, effects)
        fit = calibrate_session(imu, reference, replica_options(self, effects))
        fit.extra["stamp_resolution_s"] = self.stamp_resolution_s
        if self.static_blocks is not None:
            fit.extra["static_blocks"] = render_static_blocks(self, seed, effects)
        return Replica(seed, fit, {h: compute_statistics(fit, h) for h in halves})


@dataclass(frozen=True)
class BlockSpec:
    """What the block means of a twin replica's long static recording are rendered from.

    Attributes
    ----------
    t_s : ndarray, shape (k,)
        Mean time of each block since the recording's first row (s), the session's.
    samples : dict
        Sensor -> ndarray, shape (k,): samples of the sensor in each block, the session's.
    samples_per_block : int
        Rows per block.
    rate_hz : float
        Rows per second of the recording.
    temperature : tuple or None
        (column name, ndarray (k,) of block-mean temperatures, deg C), carried over to the
        replicas block by block.
    """

    t_s: np.ndarray
    samples: dict
    samples_per_block: int
    rate_hz: float
    temperature: tuple | None = None

    @classmethod
    def of(cls, blocks: StaticBlocks, rate_hz: float) -> BlockSpec:
        """The spec of a session's block means (``rate_hz``: its window's row rate)."""
        table = blocks.table
        col = temperature_column(table)
        return cls(
            table[TIME].to_numpy(dtype=float) - blocks.start_s,
            {s: table[COUNT_COLUMNS[s]].to_numpy(dtype=float) for s in SENSORS
             if COUNT_COLUMNS[s] in table.columns},
            blocks.samples_per_block,
            rate_hz,
            (col, table[col].to_numpy(dtype=float)) if col else None,
        )  # fmt: skip

    def describe(self) -> dict:
        """JSON-ready summary."""
        return {
            "blocks": int(len(self.t_s)),
            "samples_per_block": int(self.samples_per_block),
            "duration_s": float(self.t_s[-1] + 0.5 * self.samples_per_block / self.rate_hz),
        }


def quantised_moments(value: np.ndarray, std: float, step: float) -> tuple[np.ndarray, np.ndarray]:
    """Mean and variance of ``step * round((value + e) / step)`` with ``e ~ N(0, std^2)``.

    Parameters
    ----------
    value : ndarray
        Noise-free readings (SI), any shape.
    std : float
        White-noise std (SI).
    step : float
        Quantisation step (SI per count).

    Returns
    -------
    mean, var : ndarray
        Same shape as ``value`` (SI, SI^2). With ``std`` well above ``step`` they tend to
        ``value`` and ``std^2 + step^2 / 12``; below it the rounding's bias and its smaller
        spread are kept (the session's block means carry them too).
    """
    u = np.asarray(value, dtype=float) / step
    s = std / step
    if s > 3:  # the rounding error is uniform and independent of the value to < 1e-30
        return u * step, np.full(u.shape, std**2 + step**2 / 12)
    half = int(np.ceil(6 * s)) + 2
    k = np.rint(u)[..., None] + np.arange(-half, half + 1)
    if s > 0:
        cdf = stats.norm.cdf((k + 0.5 - u[..., None]) / s) - stats.norm.cdf(
            (k - 0.5 - u[..., None]) / s
        )
    else:
        cdf = (k == np.rint(u)[..., None]).astype(float)
    mean = np.sum(k * cdf, axis=-1)
    var = np.sum(k**2 * cdf, axis=-1) - mean**2
    return mean * step, np.maximum(var, 0.0) * step**2


def render_static_blocks(twin: Twin, seed: int, effects: tuple = ()) -> StaticBlocks:
    """The block means of a replica's long static recording, drawn at the block rate.

    The replica's static plan (a hold, :func:`imucal.sim.plan_session` with the replica's seed,
    so the same attitude as its rendered window) is evaluated at the session's block times;
    the effects' ``on_truth``, ``on_true_signals`` and ``on_readings`` act on the block rate
    (``rate_hz / samples_per_block``; their time-dependent terms are slow against a block);
    the packet hook is not called (a block mean does not see receive times or a lost sample).
    Each block mean is the mean of its quantised samples (:func:`quantised_moments`) plus a
    Gaussian of their variance over the block's samples of that sensor.

    Parameters
    ----------
    twin : Twin
        With ``static_blocks``.
    seed : int
    effects : tuple of imucal.sim.Effect

    Returns
    -------
    StaticBlocks
    """
    spec = twin.static_blocks
    truth = twin.truth
    for effect in effects:
        truth = effect.on_truth(truth)
    plans, starts = plan_session(twin.config, seed)
    motion = plans["static"].motion
    t = spec.t_s
    ctx = RecordingContext(
        "static", spec.rate_hz / spec.samples_per_block, starts["static"] + t[0],
        SENSITIVITY, seed, motion, truth.calibration, {},
    )  # fmt: skip
    state = evaluate_motion(motion, t)
    true = true_signals(state, truth.world)
    for effect in effects:
        true = effect.on_true_signals(true, state, ctx)
    zero = dict.fromkeys(SENSORS, 0.0)
    readings = sensor_readings(truth.calibration, true, zero, stream_rng(seed, "blocks/static"))
    for effect in effects:
        readings = effect.on_readings(readings, true, state, ctx)
    rng = stream_rng(seed, "noise/static blocks")
    columns = {TIME: t}
    for s in SENSORS:
        if s not in spec.samples:
            continue
        step = float(SENSITIVITY[s])  # the quantiser of the replica's window
        mean, var = quantised_moments(readings.sensor(s), truth.noise[s], step)
        n = spec.samples[s][:, None]
        with np.errstate(invalid="ignore", divide="ignore"):
            values = mean + rng.standard_normal(mean.shape) * np.sqrt(var / n)
        values[spec.samples[s] == 0] = np.nan
        columns.update(zip(SENSOR_COLUMNS[s], values.T, strict=True))
        columns[COUNT_COLUMNS[s]] = spec.samples[s]
    if spec.temperature is not None:
        columns[spec.temperature[0]] = spec.temperature[1]
    table = pd.DataFrame(columns)
    n_rows = int(spec.samples_per_block * len(t))
    return StaticBlocks(table, spec.samples_per_block, 0.0, n_rows)


def replica_options(twin: Twin, effects: tuple = ()) -> PipelineOptions:
    """Pipeline options of a replica: the session's, with the twin's sensor ranges and without
    the parameters' covariance.

    The twin's sensors have no range below the int16 full scale (the paper's model has none);
    an effect that sets the dataset's ranges (saturation) gives the replica its clip levels,
    and the pipeline knows them as a dataset would declare them. A replica is measured by its
    statistics, its effect estimators and its calibration's values, none of which reads the
    covariance, so its chain skips the uncertainty propagation (the fitted values are the same).

    Parameters
    ----------
    twin : Twin
    effects : tuple of imucal.sim.Effect

    Returns
    -------
    PipelineOptions
    """
    ranges = {s: INT16_MAX for s in SENSORS}
    for effect in effects:
        ranges.update(effect.dataset_overrides().get("range_counts", {}))
    return replace(twin.options, range_counts=ranges, with_covariance=False)


def _durations(segments: pd.DataFrame, recording: str, kind: str) -> np.ndarray:
    rows = segments[(segments["recording"] == recording) & (segments["kind"] == kind)]
    return (rows["end_s"] - rows["start_s"]).to_numpy(dtype=float)


def static_noise(fit: SessionFit, sensitivity: Mapping) -> dict:
    """White-noise std per sensor (SI, before calibration) from the static data.

    The std of first differences of the raw readings over static segments, divided by sqrt(2)
    (insensitive to slow drift), with the quantisation variance ``LSB^2/12`` removed (the twin
    quantises again); the magnetometer on its fresh samples only. Averaged over the axes.

    Returns
    -------
    dict
        Sensor -> std (m/s^2, rad/s, normalised).
    """
    names = ["static"] if "static" in fit.imu else ["rotation3d", "cube"]
    out = {}
    for s in SENSORS:
        diffs = []
        for name in names:
            rows = fit.segments[
                (fit.segments["recording"] == name)
                & fit.segments["kind"].isin(["static", "position"])
            ]
            table = fit.imu[name]
            for r in rows.itertuples(index=False):
                x = table.iloc[int(r.start_index) : int(r.end_index)][list(SENSOR_COLUMNS[s])]
                x = x.to_numpy(dtype=float)
                x = x[np.all(np.isfinite(x), axis=1)]
                if len(x) > 2:
                    diffs.append(np.diff(x, axis=0))
        if not diffs:
            raise ValueError(f"no static samples of {s} to estimate its noise from")
        d = np.vstack(diffs)
        # robust std of the differences (a handling bump in a static segment must not count)
        var = (1.4826 * np.median(np.abs(d - np.median(d, axis=0)), axis=0)) ** 2 / 2
        var = var - float(sensitivity[s]) ** 2 / 12
        out[s] = float(np.sqrt(np.maximum(var, 0.0).mean()))
    return out


def reference_noise(reference: pd.DataFrame | None) -> dict:
    """White-noise std of the reference per sensor from its second differences (robust)."""
    if reference is None:
        return dict(REFERENCE_NOISE)
    out = {}
    for s in SENSORS:
        x = reference[list(SENSOR_COLUMNS[s])].to_numpy(dtype=float)
        d2 = np.diff(x, n=2, axis=0)
        d2 = d2[np.all(np.isfinite(d2), axis=1)]
        mad = 1.4826 * np.median(np.abs(d2 - np.median(d2, axis=0)), axis=0)
        out[s] = float(np.mean(mad) / np.sqrt(6))
    return out


def field_dip_rad(fit: SessionFit) -> float:
    """Magnetic inclination seen by the calibrated sensors in the static rotation3d pauses.

    ``sin(dip) = -a.m / (|a||m|)`` with gravity's specific force pointing up.
    """
    rows = fit.segments[
        (fit.segments["recording"] == "rotation3d") & (fit.segments["kind"] == "static")
    ]
    acc = calibrated(fit, "rotation3d", "acc")
    mag = calibrated(fit, "rotation3d", "mag")
    sines = []
    for r in rows.itertuples(index=False):
        sl = slice(int(r.start_index), int(r.end_index))
        m = mag[sl][np.all(np.isfinite(mag[sl]), axis=1)]
        if len(m) == 0:
            continue
        a, m = acc[sl].mean(axis=0), m.mean(axis=0)
        sines.append(-a @ m / (np.linalg.norm(a) * np.linalg.norm(m)))
    if not sines:
        raise ValueError("no static rotation3d pause with magnetometer samples to measure the dip")
    return float(np.arcsin(np.clip(np.median(sines), -1, 1)))


def protocol_config(fit: SessionFit) -> tuple[ProtocolConfig, list[str]]:
    """The protocol timing of a session, read from its segments and calibrated rates.

    Returns
    -------
    config : ProtocolConfig
    notes : list of str
    """
    seg = fit.segments
    notes = []
    statics = _durations(seg, "rotation3d", "static")
    phases = seg[(seg["recording"] == "rotation3d") & (seg["kind"] == "phase")].set_index("label")
    gyr = calibrated(fit, "rotation3d", "gyr")
    turns, rates, ramps, clipped = [], [], [], {}
    for axis, default_turns, default_rate in zip("xyz", (2.0, -2.0, 2.0), (50.0, 50.0, 60.0)):
        if axis not in phases.index:
            notes.append(f"phase {axis} not found; the twin uses the default protocol's")
            turns.append(default_turns)
            rates.append(default_rate)
            continue
        r = phases.loc[axis]
        a, b = int(r.start_index), int(r.end_index)
        n = b - a
        middle = np.linalg.norm(gyr[a + n // 5 : b - n // 5], axis=1)
        rate = float(np.degrees(np.median(middle)))
        if np.isfinite(r.turns):
            t = float(np.round(r.turns * 2) / 2) or default_turns
        else:  # clipped at the gyroscope range: the raw angle is only a lower bound
            t = float(r.sense) * abs(default_turns)
            # its rate too: the clipped readings are a lower bound of it
            clipped[len(rates)] = float(r.end_s - r.start_s)
        turns.append(t)
        rates.append(rate)
        if not np.isfinite(r.turns):
            continue
        ramps.append((r.end_s - r.start_s) - abs(t) * 360 / rate)
    ramp = float(np.clip(np.median(ramps), 0.2, 5.0)) if ramps else 1.5
    for i, duration in clipped.items():
        # the phase lasts its turns at its rate plus the ramps of the phases read whole, so
        # that the twin turns as fast as the session did and clips as long (the clipped
        # readings only bound the rate from below)
        source = "its clipped readings' rate, a lower bound"
        if duration > ramp:
            rates[i] = max(rates[i], abs(turns[i]) * 360 / (duration - ramp))
            source = "from its duration"
        notes.append(
            f"phase {'xyz'[i]} clipped: its turns unknown, the twin uses {turns[i]:+g} at "
            f"{rates[i]:.0f} deg/s ({source})"
        )
    transitions = _durations(seg, "rotation3d", "transition")
    positions = _durations(seg, "cube", "position")
    cube = seg[(seg["recording"] == "cube") & (seg["kind"] == "position")].sort_values("start_s")
    gaps = (cube["start_s"].to_numpy()[1:] - cube["end_s"].to_numpy()[:-1]) if len(cube) > 1 else []
    kwargs = {
        "rotation3d_static_s": float(statics[0]) if len(statics) else 11.0,
        "phase_turns": tuple(turns),
        "phase_rate_dps": tuple(rates),
        "phase_ramp_s": ramp,
        "pause_s": float(np.median(statics[1:])) if len(statics) > 1 else 3.5,
        "transition_s": float(np.median(transitions)) if len(transitions) else 3.7,
    }
    if len(positions):
        kwargs["cube_position_s"] = (float(positions.min()), float(positions.max()))
    if len(gaps):
        kwargs["cube_move_s"] = (float(np.min(gaps)), float(np.max(gaps)))
    ratetable = fit.imu.get("ratetable")
    rt = fit.artifacts["gyr_table"]
    runs = seg[(seg["recording"] == "ratetable") & (seg["kind"] == "run")].sort_values("start_s")
    if ratetable is not None and len(runs):
        plateau = float(np.median(runs["end_s"] - runs["start_s"]))
        gap = float(np.median(runs["start_s"].to_numpy()[1:] - runs["end_s"].to_numpy()[:-1]))
        run_ramp = 1.0
        kwargs.update(
            ratetable_axes=tuple(dict.fromkeys(runs["axis"])),
            rates_dps=tuple(float(x) for x in sorted(set(runs["rate_dps"]))),
            run_plateau_s=plateau,
            run_ramp_s=run_ramp,
            run_pause_s=float(max(gap - 2 * run_ramp, 0.5)),
        )
        notes.append("rate-table spin-up time not observable from the segments; 1 s assumed")
        del rt
    if "static" in fit.imu:
        t = fit.imu["static"][TIME].to_numpy()
        kwargs["static_s"] = float(t[-1] - t[0])
    return ProtocolConfig(**kwargs), notes


def build_twin(fit: SessionFit, options: PipelineOptions) -> Twin:
    """The twin of a fitted session (see the module docstring).

    Parameters
    ----------
    fit : SessionFit
        The session run through :func:`imucal.pipeline.full.calibrate_session`.
    options : PipelineOptions

    Returns
    -------
    Twin
    """
    noise = static_noise(fit, options.sensitivity)
    dip = field_dip_rad(fit)
    mounting = np.zeros(3)
    if fit.reference is not None:
        mounting = _mounting_rotvec(fit)
    truth = Truth(
        calibration=fit.calibration,
        world=World(gravity_m_s2=options.gravity_m_s2, dip_rad=dip),
        noise=noise,
        reference_noise=reference_noise(fit.reference),
        mounting_rotvec_rad=mounting,
        preset="twin",
    )
    config, notes = protocol_config(fit)
    extra = {}
    for name, table in fit.imu.items():
        cols = [
            c
            for c in table.columns
            if c not in (TIME, SEQ) and not c.startswith(("acc_", "gyr_", "mag_"))
        ]
        if cols:
            t = table[TIME].to_numpy(dtype=float)
            extra[name] = {c: (t - t[0], table[c].to_numpy(dtype=float)) for c in cols}
    notes.append(
        "noise: robust std of first differences of static raw readings, quantisation removed"
    )
    notes.append(
        "sensor ranges: none below the int16 full scale (the paper's model has no range); "
        f"declared {dict(options.range_counts)} counts"
    )
    spec = None
    blocks = fit.extra.get("static_blocks")
    if blocks is not None:
        t = fit.imu["static"][TIME].to_numpy(dtype=float)
        spec = BlockSpec.of(blocks, (len(t) - 1) / (t[-1] - t[0]))
        notes.append(
            f"static recording of {blocks.n_rows} rows: its first {STATIC_WINDOW_S:g} s at full "
            f"rate and {len(blocks.table)} block means of {blocks.samples_per_block} rows"
        )
    resolution = max(stamp_resolution(t[TIME].to_numpy(dtype=float)) for t in fit.imu.values())
    return Twin(
        truth, config, options, tuple(r for r in TWIN_RECORDINGS if r in fit.imu),
        fit.reference is not None, extra, notes, spec, resolution,
    )  # fmt: skip


def _mounting_rotvec(fit: SessionFit) -> np.ndarray:
    """Mounting of the reference (``v_B = R v_ref``) from static rotation3d gravity and field."""
    from imucal import validation as val

    acc = calibrated(fit, "rotation3d", "acc")
    ta = fit.time_alignment
    t_mod = val.packet_times(
        fit.imu["rotation3d"][TIME].to_numpy(), fit.imu["rotation3d"][SEQ].to_numpy()
    )
    t_ref = val.packet_times(fit.reference[TIME].to_numpy(), fit.reference[SEQ].to_numpy())
    # reference sample nearest each module sample through the fitted clock
    t_on_ref = ta.offset_s + (1 + ta.drift_ppm * 1e-6) * t_mod
    idx = np.clip(np.searchsorted(t_ref, t_on_ref), 0, len(t_ref) - 1)
    ref_acc = fit.reference[["acc_x", "acc_y", "acc_z"]].to_numpy(dtype=float)[idx]
    ref_gyr = fit.reference[["gyr_x", "gyr_y", "gyr_z"]].to_numpy(dtype=float)[idx]
    gyr = calibrated(fit, "rotation3d", "gyr")
    good = np.all(np.isfinite(ref_acc), axis=1)
    lp = np.r_[acc[good], gyr[good] * 10]
    lr = np.r_[ref_acc[good], ref_gyr[good] * 10]
    rot, _ = Rotation.align_vectors(lp, lr)
    return rot.as_rotvec()


def _replica_tables(session, twin: Twin) -> tuple[dict, pd.DataFrame | None]:
    imu = {}
    for rec in twin.recordings:
        table = session.si_frame(rec)
        for col, (t0, values) in twin.extra_columns.get(rec, {}).items():
            t = table[TIME].to_numpy(dtype=float)
            table[col] = np.interp(t - t[0], t0, values)
        imu[rec] = table
    reference = None
    if twin.has_reference:
        export = MtManagerExport(session.reference, {}, REFERENCE_RATE_HZ, 1)
        reference = reference_to_table(export)
    return imu, reference


def render_replica(twin: Twin, seed: int, effects: tuple = ()) -> tuple[dict, pd.DataFrame | None]:
    """Render one replica of the twin (optionally with simulator effects) as ingested tables.

    Parameters
    ----------
    twin : Twin
    seed : int
        Seeds the protocol's random choices and the noise. The same seed with and without an
        effect gives the same noise (the simulator draws each effect from its own stream), so
        the difference isolates the effect.
    effects : tuple of imucal.sim.Effect

    Returns
    -------
    imu : dict of str to DataFrame
        Ingested IMU recordings (SI), as :func:`imucal.ingest.ingest_recording` gives them.
    reference : DataFrame or None
    """
    session = simulate_session(twin.truth, seed, twin.config, tuple(effects), name="twin")
    return _replica_tables(session, twin)
