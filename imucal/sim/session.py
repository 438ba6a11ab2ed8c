"""A complete simulated calibration session: render it in memory, write it as a dataset folder.

The folder holds ``dataset.yaml``, one raw CSV per IMU recording (counts, 100 Hz acc/gyro, 10 Hz
magnetometer), ``mtx_rotation3d.txt`` (the reference's MT Manager export) and ``truth.json``
(everything the session was rendered from, including the true segment boundaries). The same
seed gives byte-identical files.
"""

from __future__ import annotations

import dataclasses
import json
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from imucal.calibration import CONVENTION, FRAME
from imucal.columns import MAG, SENSORS, SEQ_MODULUS
from imucal.constants import SESSION_GAP_S
from imucal.ingest import counts_to_si
from imucal.sim.effects import Effect, RecordingContext, make_effect, stream_rng
from imucal.sim.motion import evaluate_motion
from imucal.sim.packets import PacketLog, build_packet_log, to_frame
from imucal.sim.protocol import PLANNERS, ProtocolConfig, RecordingPlan
from imucal.sim.reference import ReferenceClock, format_mt_export, render_reference
from imucal.sim.sensors import quantise, sensor_readings, true_signals
from imucal.sim.truth import Truth, make_truth

#: Packet rate of the module (acc/gyro), Hz; the magnetometer runs at a tenth of it.
RATE_HZ = 100.0
#: Update rate of the reference, Hz.
REFERENCE_RATE_HZ = 100.0
#: Default SI unit per raw count (the conformance session's values).
SENSITIVITY = {"acc": 0.00239501953125, "gyr": 0.0002664624812205083, "mag": 0.001}
#: File name of each recording in the dataset folder.
FILES = {
    "rotation3d": "rotation3d.csv",
    "cube": "cube.csv",
    "ratetable": "ratetable.csv",
    "static": "static.csv",
    "reference": "mtx_rotation3d.txt",
}
#: Effects switched on by a preset (the CLI's ``--effect`` adds to or replaces them by name).
PRESET_EFFECTS = {
    "paper": {},
    "random": {},
    "mems": {},
    "demo": {
        "packet_loss": {"fraction": 0.005, "model": "gilbert", "burst_mean": 4.0},
        "time_offset": {"offset_s": 0.32, "drift_ppm": 10.0},
    },
}


@dataclass(frozen=True)
class Session:
    """A rendered session (see :func:`simulate_session`).

    Attributes
    ----------
    name, description : str
    seed : int
    truth : Truth
    config : ProtocolConfig
    effects : tuple of Effect
    sensitivity : dict
        SI unit per count per sensor.
    plans : dict
        Recording -> nominal :class:`~imucal.sim.protocol.RecordingPlan` (motion and true
        segments, what the pipeline is told).
    logs : dict
        Recording -> :class:`~imucal.sim.packets.PacketLog` (what the raw CSV holds).
    clock : ReferenceClock
    reference : DataFrame
        The reference's export table.
    clipped : dict
        Recording -> sensor -> number of counts clipped to the int16 range.
    rendered : dict
        Recording -> the plan actually rendered (after the effects' ``on_plan``; the same as
        ``plans`` unless an effect such as ``placement_error`` changed the motion).
    realised : dict
        Effect name -> recording -> random draws the effects recorded (see
        :meth:`~imucal.sim.effects.RecordingContext.record`).
    """

    name: str
    description: str
    seed: int
    truth: Truth
    config: ProtocolConfig
    effects: tuple
    sensitivity: dict
    plans: dict
    logs: dict
    clock: ReferenceClock
    reference: pd.DataFrame
    clipped: dict
    rendered: dict = dataclasses.field(default_factory=dict)
    realised: dict = dataclasses.field(default_factory=dict)

    def frame(self, recording: str) -> pd.DataFrame:
        """The raw-CSV table of an IMU recording."""
        return to_frame(self.logs[recording])

    def si_frame(self, recording: str) -> pd.DataFrame:
        """An IMU recording as the workflow's ingest gives it: SI units, NaN where a row has no
        magnetometer sample."""
        frame = self.frame(recording).astype({c: "float64" for c in MAG})
        return counts_to_si(frame, self.sensitivity)

    def dataset_dict(self, sealed: bool = False) -> dict:
        """Content of ``dataset.yaml``; ``sealed`` declares the session simulated without naming
        its effects, seed or truth (a blind session's answer key is kept apart)."""
        rates = [int(r) if float(r).is_integer() else float(r) for r in self.config.rates_dps]
        d = {
            "name": self.name,
            "description": self.description,
            "simulated": (
                {"by": "imucal.sim (blind session, answer key sealed)"}
                if sealed
                else {"by": self.rendered_by(), "truth": "truth.json"}
            ),
            "gravity_m_s2": self.truth.world.gravity_m_s2,
            "sensitivity": dict(self.sensitivity),
            "recordings": {rec: FILES[rec] for rec in (*self.plans, "reference")},
            "ratetable": {"axes": list(self.config.ratetable_axes), "rates_dps": rates},
        }
        for effect in self.effects:
            d.update(effect.dataset_overrides())
        return d

    def rendered_by(self) -> str:
        """What rendered the session, for dataset.yaml's ``simulated`` declaration."""
        effects = ", ".join(e.name for e in self.effects) or "none"
        return f"imucal.sim, preset {self.truth.preset}, seed {self.seed}, effects: {effects}"

    def truth_dict(self) -> dict:
        """Content of ``truth.json`` (conformance format plus world, noise, reference, segments)."""
        out: dict = {}
        for s in SENSORS:
            cal = self.truth.calibration.sensor(s)
            dec = cal.decomposition
            out[s] = {
                "bias": cal.bias.tolist(),
                "matrix": cal.matrix.tolist(),
                "scale": dec.scale.tolist(),
                "xi": dec.xi_rad.tolist(),
                "alpha": dec.alpha_rad.tolist(),
            }
        world = self.truth.world
        out.update(
            {
                "effects": {e.name: e.params() for e in self.effects},
                **({"effects_realised": self.realised} if self.realised else {}),
                "seed": self.seed,
                "convention": CONVENTION,
                "frame": FRAME,
                "preset": self.truth.preset,
                "gravity_m_s2": world.gravity_m_s2,
                "field": {
                    "dip_deg": float(np.degrees(world.dip_rad)),
                    "inclination_rad": world.dip_rad,
                    "norm": 1.0,
                    "world": world.field.tolist(),
                    "world_frame": "x magnetic north, y west, z up; gravity along -z",
                },
                "noise": dict(self.truth.noise),
                "sample_rate_hz": RATE_HZ,
                "mag_rate_hz": RATE_HZ / 10,
                "reference": {
                    "mounting_rotvec_rad": self.truth.mounting_rotvec_rad.tolist(),
                    "mounting_matrix": self.truth.mounting.as_matrix().tolist(),
                    "time_offset_s": self.clock.offset_s,
                    "clock_drift_ppm": self.clock.drift_ppm,
                    "noise": dict(self.truth.reference_noise),
                    "rate_hz": REFERENCE_RATE_HZ,
                    "convention": (
                        "v_B = mounting_matrix @ v_ref; tau = (t_module + time_offset_s) * "
                        "(1 + clock_drift_ppm * 1e-6) with tau the time since the first "
                        "reference sample and t_module the t_s axis of rotation3d"
                    ),
                },
                "protocol": dataclasses.asdict(self.config),
                "clipped_counts": self.clipped,
                "segments": [
                    seg.to_dict() for plan in self.plans.values() for seg in plan.segments
                ],
            }
        )
        return out


def preset_effects(preset: str, extra: tuple[Effect, ...] = ()) -> tuple[Effect, ...]:
    """The effects of a preset, with ``extra`` added or replacing those of the same name."""
    if preset not in PRESET_EFFECTS:
        raise ValueError(f"unknown preset {preset!r}; expected one of {sorted(PRESET_EFFECTS)}")
    chosen = {name: make_effect(name, **params) for name, params in PRESET_EFFECTS[preset].items()}
    chosen.update({e.name: e for e in extra})
    return tuple(chosen.values())


def _seq_origin(plans: dict, starts: dict, rng: np.random.Generator) -> int:
    """Counter value at session time 0, chosen so that the longest recording wraps inside."""
    longest = max(plans, key=lambda r: plans[r].motion.duration_s)
    n = plans[longest].motion.duration_s * RATE_HZ
    wrap_at = round(starts[longest] * RATE_HZ + rng.uniform(0.2, 0.8) * n)
    return -wrap_at % SEQ_MODULUS


def render_recording(
    plan: RecordingPlan,
    truth: Truth,
    effects: tuple[Effect, ...],
    ctx: RecordingContext,
    seq_start: int,
) -> tuple[PacketLog, dict]:
    """Render one recording of the motion ``plan.motion`` (``ctx.motion`` is the same).

    Returns
    -------
    log : PacketLog
        The packets (counts at :data:`RATE_HZ`, the magnetometer on every 10th).
    clipped : dict
        Sensor -> counts clipped to the int16 range.
    """
    n = int(np.floor(plan.motion.duration_s * RATE_HZ)) + 1
    state = evaluate_motion(plan.motion, np.arange(n) / RATE_HZ)
    true = true_signals(state, truth.world)
    for effect in effects:
        true = effect.on_true_signals(true, state, ctx)
    readings = sensor_readings(
        truth.calibration, true, truth.noise, stream_rng(ctx.seed, f"noise/{plan.recording}")
    )
    for effect in effects:
        readings = effect.on_readings(readings, true, state, ctx)
    counts, clipped = {}, {}
    for s in SENSORS:
        counts[s], clipped[s] = quantise(readings.sensor(s), ctx.sensitivity[s])
    log = build_packet_log(counts, seq_start, RATE_HZ)
    for effect in effects:
        log = effect.on_packets(log, ctx)
    return log, clipped


def plan_session(
    config: ProtocolConfig, seed: int
) -> tuple[dict[str, RecordingPlan], dict[str, float]]:
    """The nominal plan of every recording and its start on the session clock.

    Parameters
    ----------
    config : ProtocolConfig
    seed : int
        Seeds the protocol's random choices (the ``protocol`` stream, as
        :func:`simulate_session`).

    Returns
    -------
    plans : dict
        Recording -> :class:`~imucal.sim.protocol.RecordingPlan`, in protocol order.
    starts : dict
        Recording -> start (s) on the session clock (``SESSION_GAP_S`` between recordings).
    """
    protocol_rng = stream_rng(seed, "protocol")
    plans = {rec: planner(config, protocol_rng) for rec, planner in PLANNERS.items()}
    starts, t = {}, 0.0
    for rec, plan in plans.items():
        starts[rec] = t
        t += plan.motion.duration_s + SESSION_GAP_S
    return plans, starts


def simulate_session(
    truth: Truth,
    seed: int,
    config: ProtocolConfig | None = None,
    effects: tuple[Effect, ...] = (),
    name: str = "sim",
    description: str | None = None,
    sensitivity: dict | None = None,
) -> Session:
    """Render every recording of a calibration session from a known truth.

    Parameters
    ----------
    truth : Truth
    seed : int
        Seeds the protocol's random choices (headings, handling motions, hold times), the
        noise, the packet counter and every effect, each from its own stream.
    config : ProtocolConfig, optional
        Timing of the protocol; default ``ProtocolConfig()``.
    effects : tuple of Effect
        Applied in this order at each hook, stably sorted by ``priority`` (see
        :mod:`imucal.sim.effects.base`).
    name : str
        Dataset name, ``[a-z0-9_]+``.
    description : str, optional
    sensitivity : dict, optional
        SI unit per count; default :data:`SENSITIVITY`.

    Returns
    -------
    Session

    Notes
    -----
    The recordings follow one another on a session clock (``SESSION_GAP_S`` apart), which the
    16-bit counter and time-dependent effects (temperature, bias instability) run on. The
    effects' ``on_truth`` runs first (the returned session holds the changed truth), then per
    recording ``on_plan`` (the session's ``plans`` and truth.json keep the nominal plans).
    """
    names = [e.name for e in effects]
    if len(set(names)) != len(names):
        raise ValueError(f"each effect may be given once, got {names}")
    effects = tuple(sorted(effects, key=lambda e: e.priority))
    sensitivity = dict(SENSITIVITY if sensitivity is None else sensitivity)
    if description is None:
        description = (
            f"SIMULATED calibration session (imucal.sim, preset {truth.preset}, seed {seed}); "
            "the ground truth is in truth.json."
        )
    config = ProtocolConfig() if config is None else config
    for effect in effects:
        truth = effect.on_truth(truth)
    plans, starts = plan_session(config, seed)
    origin = _seq_origin(plans, starts, stream_rng(seed, "seq"))
    logs, clipped, rendered, realised = {}, {}, {}, {}
    for rec, plan in plans.items():
        ctx = RecordingContext(
            rec, RATE_HZ, starts[rec], sensitivity, seed, None, truth.calibration, realised
        )
        for effect in effects:
            plan = effect.on_plan(plan, ctx)
        rendered[rec] = plan
        ctx = dataclasses.replace(ctx, motion=plan.motion)
        seq_start = (origin + round(starts[rec] * RATE_HZ)) % SEQ_MODULUS
        logs[rec], clipped[rec] = render_recording(plan, truth, effects, ctx, seq_start)
    clock = ReferenceClock()
    for effect in effects:
        clock = effect.on_reference_clock(clock)
    ref_rng = stream_rng(seed, "reference")

    def sample_times(tau: np.ndarray) -> np.ndarray:
        for effect in effects:
            tau = effect.on_reference_times(tau, stream_rng(seed, f"{effect.name}/reference"))
        return tau

    reference = render_reference(
        rendered["rotation3d"].motion,
        truth.world,
        truth.mounting,
        truth.reference_noise,
        clock,
        REFERENCE_RATE_HZ,
        int(ref_rng.integers(100_000, 5_000_000)),
        ref_rng,
        sample_times,
    )
    return Session(
        name, description, seed, truth, config, tuple(effects), sensitivity, plans, logs, clock,
        reference, clipped, rendered, realised,
    )  # fmt: skip


def write_session(session: Session, folder: str | Path, sealed: bool = False) -> Path:
    """Write a session as a dataset folder (created if needed; files are overwritten).

    With ``sealed`` the folder holds no ``truth.json`` and its ``dataset.yaml`` does not name the
    effects, seed or preset (:meth:`Session.dataset_dict`); the caller keeps the truth.

    Returns
    -------
    Path
        The folder.
    """
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    (out / "dataset.yaml").write_text(
        yaml.safe_dump(session.dataset_dict(sealed), sort_keys=False, width=1000)
    )
    for rec in session.logs:
        session.frame(rec).to_csv(
            out / FILES[rec], index=False, float_format="%.4f", lineterminator="\n"
        )
    (out / FILES["reference"]).write_text(format_mt_export(session.reference, REFERENCE_RATE_HZ))
    if not sealed:
        (out / "truth.json").write_text(
            json.dumps(session.truth_dict(), indent=2, allow_nan=False) + "\n"
        )
    return out


def simulate(
    folder: str | Path,
    preset: str = "paper",
    seed: int = 0,
    effects: tuple[Effect, ...] = (),
    static_s: float | None = None,
    name: str | None = None,
    truth_seed: int | None = None,
) -> Session:
    """Render a preset session and write it to ``folder`` (what ``imucal simulate`` does).

    Parameters
    ----------
    folder : str or Path
    preset : str
        'paper', 'random', 'demo' or 'mems' (see :mod:`imucal.sim.truth`).
    seed : int
    effects : tuple of Effect
        Added to the preset's effects, replacing one of the same name.
    static_s : float, optional
        Length of the static recording (s); default that of :class:`ProtocolConfig`.
    name : str, optional
        Dataset name; default the folder name, lower-cased, other characters as ``_``.
    truth_seed : int, optional
        Seed of the truth (the sensor unit's parameters) when it is not ``seed``: sessions of
        one unit share it and differ in ``seed`` (noise, protocol timing).

    Returns
    -------
    Session
    """
    folder = Path(folder)
    if name is None:
        name = re.sub(r"[^a-z0-9_]", "_", folder.resolve().name.lower())
    truth = make_truth(preset, stream_rng(seed if truth_seed is None else truth_seed, "truth"))
    config = ProtocolConfig() if static_s is None else ProtocolConfig(static_s=static_s)
    session = simulate_session(
        truth, seed, config, preset_effects(preset, tuple(effects)), name=name
    )
    write_session(session, folder)
    return session
