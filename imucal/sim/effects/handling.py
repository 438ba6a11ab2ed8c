"""Effects of a module held by hand instead of resting on a fixture: hand_tremor."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from imucal.sim.effects.base import Effect, Magnitude, RecordingContext, register
from imucal.sim.motion import KinematicState, Motion, Tremor
from imucal.sim.protocol import RecordingPlan
from imucal.sim.sensors import Signals

#: Sinusoids per body axis in each band (sway, tremor).
COMPONENTS = 2
#: Recordings whose positions are held by hand: the cube, and a module tumbled by hand
#: (:func:`imucal.sim.protocol.plan_tumble`).
HELD = ("cube", "poses")


@register
@dataclass(frozen=True)
class HandTremor(Effect):
    """Static positions held by hand: physiological tremor plus a slow sway.

    Every position of the ``cube`` recording (and of a hand-tumbled ``poses`` recording) gets
    a small rotation on top of its nominal orientation (a :class:`~imucal.sim.motion.Tremor`, analytic, so the specific force and the
    rate stay exactly consistent): per body axis, :data:`COMPONENTS` sway sinusoids of
    amplitude ``sway_deg`` at frequencies drawn in ``sway_min_hz``..``sway_max_hz`` and
    :data:`COMPONENTS` tremor sinusoids of amplitude ``tremor_deg`` drawn in
    ``tremor_min_hz``..``tremor_max_hz``, random phases, under an envelope that rises and falls
    over ``ramp_s`` (at most half the hold) so that the handling motions still join the nominal
    positions. The other recordings, and a rest on the table before the hand picks the module
    up, are unchanged. The draws go to
    ``truth.json["effects_realised"]["hand_tremor"]["cube"]``: per position ``freq_hz``,
    ``amplitude_rad``, ``phase_rad`` (each 3 x 4: sway then tremor components, body axes x, y,
    z) and the realised ``rate_rms_rad_s`` and ``angle_rms_rad`` of the hold.

    A protocol condition (calibration without a fixture), not an error of the sensor: the gap
    diagnosis has no model of it.

    Parameters
    ----------
    sway_deg : float
        Amplitude of each sway sinusoid (deg), >= 0. Default 0.3: a hold wanders by about
        0.5 deg (RMS of the rotation angle), rate RMS about 0.8 deg/s per axis at 0.45 Hz.
    tremor_deg : float
        Amplitude of each tremor sinusoid (deg), >= 0. Default 0.01: rate RMS about
        0.5 deg/s per axis at 8 Hz (physiological tremor of a hand holding a small object:
        about 0.5-2 deg/s, energy at 4-12 Hz).
    sway_min_hz, sway_max_hz, tremor_min_hz, tremor_max_hz : float
        Frequency bands (Hz), 0 < min <= max. Defaults 0.1-0.8 and 4-12.
    ramp_s : float
        Rise and fall of the envelope (s), > 0.
    sway_mm : float
        Amplitude of each sinusoid of the hand's sway in translation (mm, world axes), >= 0:
        :data:`COMPONENTS` per axis in the sway band under the same envelope, seen by the
        accelerometer as its second derivative (at 3 mm and 0.45 Hz about 0.02 m/s^2, which a
        hold of a second does not average out; the envelope's ramps, a quarter of a second in a
        pause of half a second, add up to about 1 m/s^2 per 8 mm at a pause's ends: the hand
        settling). Default 0: the hand turns the module only.
    """

    name = "hand_tremor"
    scalable = ("sway_deg", "tremor_deg")
    sway_deg: float = 0.3
    tremor_deg: float = 0.01
    sway_min_hz: float = 0.1
    sway_max_hz: float = 0.8
    tremor_min_hz: float = 4.0
    tremor_max_hz: float = 12.0
    ramp_s: float = 0.5
    sway_mm: float = 0.0

    def __post_init__(self) -> None:
        for key in ("sway_deg", "tremor_deg", "sway_mm"):
            if not getattr(self, key) >= 0:
                raise ValueError(f"hand_tremor {key} must be >= 0, got {getattr(self, key)}")
        for band in ("sway", "tremor"):
            low, high = getattr(self, f"{band}_min_hz"), getattr(self, f"{band}_max_hz")
            if not 0 < low <= high:
                raise ValueError(
                    f"hand_tremor {band} band must satisfy 0 < min <= max Hz, got {low}..{high}"
                )
        if not self.ramp_s > 0:
            raise ValueError(f"hand_tremor ramp_s must be > 0 s, got {self.ramp_s}")

    def on_plan(self, plan: RecordingPlan, ctx: RecordingContext) -> RecordingPlan:
        if plan.recording not in HELD:
            return plan
        rng = ctx.rng(f"effect/{self.name}")
        positions = [s for s in plan.segments if s.kind == "position"]
        held = {s.start_s for s in positions}
        labels = iter(s.label for s in positions)
        pieces = []
        for piece in plan.motion.pieces:
            # a rest on the table before the hand picks the module up stays still
            if piece.profile != "hold" or piece.start_s not in held:
                pieces.append(piece)
                continue
            tremor = self._draw(rng, piece.duration_s)
            pieces.append(dataclasses.replace(piece, tremor=tremor))
            tau = np.arange(0.0, piece.duration_s, 1.0 / ctx.rate_hz)
            angle, rate, _ = tremor.angles(tau, piece.duration_s)
            ctx.record(self.name, next(labels, f"hold{len(pieces)}"), {
                "freq_hz": tremor.freq_hz.tolist(),
                "amplitude_rad": tremor.amplitude_rad.tolist(),
                "phase_rad": tremor.phase_rad.tolist(),
                "rate_rms_rad_s": np.sqrt((rate**2).mean(axis=0)).tolist(),
                "angle_rms_rad": np.sqrt((angle**2).mean(axis=0)).tolist(),
            })  # fmt: skip
        return dataclasses.replace(plan, motion=Motion(tuple(pieces)))

    def on_true_signals(
        self, signals: Signals, state: KinematicState, ctx: RecordingContext
    ) -> Signals:
        if self.sway_mm == 0 or ctx.recording not in HELD:
            return signals
        rng = ctx.rng(f"effect/{self.name}/translation")
        world = np.zeros_like(signals.acc)
        for piece in ctx.require(self.name, "motion").pieces:
            if piece.tremor is None:
                continue
            k = COMPONENTS
            # the translation's sinusoids under the rotation's envelope (Tremor's arithmetic)
            path = Tremor(
                np.full((3, k), self.sway_mm * 1e-3),
                rng.uniform(self.sway_min_hz, self.sway_max_hz, (3, k)),
                rng.uniform(0.0, 2 * np.pi, (3, k)),
                piece.tremor.ramp_s,
            )
            inside = (state.t_s >= piece.start_s) & (state.t_s < piece.end_s)
            _, _, world[inside] = path.angles(state.t_s[inside] - piece.start_s, piece.duration_s)
        # the specific force gains the hand's linear acceleration, seen in B
        return signals.with_sensor("acc", signals.acc + state.rotation.apply(world, inverse=True))

    def _draw(self, rng: np.random.Generator, duration_s: float) -> Tremor:
        k = COMPONENTS
        freq = np.hstack([
            rng.uniform(self.sway_min_hz, self.sway_max_hz, (3, k)),
            rng.uniform(self.tremor_min_hz, self.tremor_max_hz, (3, k)),
        ])  # fmt: skip
        amplitude = np.hstack([
            np.full((3, k), np.radians(self.sway_deg)),
            np.full((3, k), np.radians(self.tremor_deg)),
        ])  # fmt: skip
        phase = rng.uniform(0.0, 2 * np.pi, (3, 2 * k))
        return Tremor(amplitude, freq, phase, min(self.ramp_s, duration_s / 2))

    def magnitude(self) -> Magnitude:
        return Magnitude(
            float(np.radians(self.sway_deg)), "rad", "amplitude of each sway sinusoid per axis"
        )
