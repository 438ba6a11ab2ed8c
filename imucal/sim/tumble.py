"""A module tumbled by hand: one recording of many brief pauses, as a user without a fixture
records it.

The module rests on the table, then a hand turns it from one random orientation to the next
and holds it there for a moment (:func:`imucal.sim.protocol.plan_tumble`). It is rendered like
the protocol's recordings, from a truth with its effects (the hand's tremor and sway:
``hand_tremor``; the sensor off the wrist: ``lever_arm``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import pandas as pd

from imucal.columns import MAG
from imucal.ingest import counts_to_si
from imucal.sim.effects import Effect, RecordingContext, stream_rng
from imucal.sim.packets import PacketLog, to_frame
from imucal.sim.protocol import RecordingPlan, TumbleConfig, plan_tumble
from imucal.sim.session import RATE_HZ, SENSITIVITY, render_recording
from imucal.sim.truth import Truth


@dataclass(frozen=True)
class HandTumble:
    """A rendered hand-tumbled recording (see :func:`simulate_tumble`).

    Attributes
    ----------
    truth : Truth
    config : TumbleConfig
    effects : tuple of Effect
    sensitivity : dict
        SI unit per count per sensor.
    plan : RecordingPlan
        The nominal plan (its segments are the true rest and pauses).
    rendered : RecordingPlan
        The plan rendered (after the effects' ``on_plan``, e.g. the hand's tremor).
    log : PacketLog
    clipped : dict
        Sensor -> counts clipped to the int16 range.
    realised : dict
        The effects' random draws (effect -> ``poses`` -> key -> value).
    """

    truth: Truth
    config: TumbleConfig
    effects: tuple
    sensitivity: dict
    plan: RecordingPlan
    rendered: RecordingPlan
    log: PacketLog
    clipped: dict
    realised: dict

    def frame(self) -> pd.DataFrame:
        """The raw table (counts, as the protocol's CSV files hold them)."""
        return to_frame(self.log)

    def si_frame(self) -> pd.DataFrame:
        """The recording in SI units (NaN where a row has no magnetometer sample)."""
        frame = self.frame().astype({c: "float64" for c in MAG})
        return counts_to_si(frame, self.sensitivity)

    def pauses_s(self) -> np.ndarray:
        """The true pauses (``position`` segments), shape (poses, 2): start and end, s."""
        rows = [(s.start_s, s.end_s) for s in self.plan.segments if s.kind == "position"]
        return np.array(rows, dtype=float).reshape(-1, 2)


def simulate_tumble(
    truth: Truth,
    seed: int,
    config: TumbleConfig | None = None,
    effects: tuple[Effect, ...] = (),
    sensitivity: dict | None = None,
) -> HandTumble:
    """Render a hand-tumbled ``poses`` recording from a known truth.

    Parameters
    ----------
    truth : Truth
    seed : int
        Seeds the orientations and timing (stream ``protocol``), the noise and the effects,
        each from its own stream.
    config : TumbleConfig, optional
        Default ``TumbleConfig()``: 26 pauses of 0.5-0.9 s.
    effects : tuple of Effect
        Applied at each hook in this order, stably sorted by ``priority``.
    sensitivity : dict, optional
        SI unit per count; default :data:`imucal.sim.session.SENSITIVITY`.

    Returns
    -------
    HandTumble
    """
    config = TumbleConfig() if config is None else config
    sensitivity = dict(SENSITIVITY if sensitivity is None else sensitivity)
    effects = tuple(sorted(effects, key=lambda e: e.priority))
    for effect in effects:
        truth = effect.on_truth(truth)
    plan = plan_tumble(config, stream_rng(seed, "protocol"))
    realised: dict = {}
    ctx = RecordingContext(
        "poses", RATE_HZ, 0.0, sensitivity, seed, None, truth.calibration, realised
    )
    rendered = plan
    for effect in effects:
        rendered = effect.on_plan(rendered, ctx)
    ctx = dataclasses.replace(ctx, motion=rendered.motion)
    log, clipped = render_recording(rendered, truth, effects, ctx, 0)
    return HandTumble(truth, config, effects, sensitivity, plan, rendered, log, clipped, realised)
