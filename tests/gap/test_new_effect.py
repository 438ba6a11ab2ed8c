"""An effect added as one module: its simulator model registered with
:func:`imucal.sim.effects.register` and its spec with :func:`imucal.gap.library.register`,
nothing else of the package edited. A static recording rendered with it is diagnosed by the
static scope, which estimates the effect, renders it into its twin and names it; a recording
without it names nothing; the catalogue's contract holds with it, and it goes away with its
registrations.

The effect: the host's clock wanders against the sample clock, so that the receive times of a
static recording run ahead and behind the straight clock line by a slow sine. The static
scope's statistic ``stamp_wander_s`` (the RMS of the receive times' lower envelope about that
line, :func:`imucal.gap.streams.receive_latency`) is the only one it moves much; no effect of
the library claims it.
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass

import numpy as np
import pandas as pd
import pytest

from imucal.columns import SENSOR_COLUMNS, TIME
from imucal.gap import DiagnosisSettings
from imucal.gap.catalogue import catalogue, contract_violations
from imucal.gap.effects import EffectModel, Estimate
from imucal.gap.library import SCOPES, EffectSpec, not_observable, register, scope_library
from imucal.gap.library import unregister as unregister_spec
from imucal.gap.static import diagnose_static
from imucal.gap.statictwin import StaticTwin, render_static
from imucal.gap.streams import receive_latency
from imucal.sim import make_truth
from imucal.sim.effects import EFFECTS, Effect, Magnitude, stream_rng
from imucal.sim.effects import register as register_effect
from imucal.sim.packets import PacketLog
from imucal.sim.session import SENSITIVITY

DURATION_S = 240.0
REPLICAS = 12


# --------------------------------------------------------------------------- the new module


@dataclass(frozen=True)
class ClockWander(Effect):
    """The host's clock wanders against the sample clock: receive times off by a slow sine.

    Model: ``t_k += amplitude_s sin(2 pi t_k / period_s)`` on every received packet (the
    receiver's clock; the counter and the samples are left alone).
    """

    name = "clock_wander"
    scalable = ("amplitude_s",)
    amplitude_s: float = 0.004
    period_s: float = 120.0

    def on_packets(self, log: PacketLog, ctx) -> PacketLog:
        wander = self.amplitude_s * np.sin(2 * np.pi * log.t_s / self.period_s)
        return log.with_times(log.t_s + wander)

    def magnitude(self) -> Magnitude:
        return Magnitude(self.amplitude_s, "s", "amplitude of the receive clock's wander")


def estimate_clock_wander(streams, half) -> Estimate:
    """Amplitude of a sine with the receive times' wander about the clock line (its RMS times
    sqrt(2), pooled over the streams), at the effect's default period; detect: the RMS (s)."""
    wander = np.concatenate(
        [receive_latency(st.half(half).t_s, st.half(half).rate_hz)[1] for st in streams.values()]
    )
    rms = float(np.sqrt(np.mean(wander**2)))
    return Estimate({"amplitude_s": math.sqrt(2) * rms, "period_s": ClockWander.period_s}, rms)


CLOCK_WANDER = EffectSpec(
    name="clock_wander",
    description="the host clock wandering slowly against the sample clock",
    kind="systematic",
    scopes={
        **{scope: "only a static recording's receive times are read for it" for scope in SCOPES},
        "static": EffectModel(
            "clock_wander",
            estimate_clock_wander,
            (("ingest", "*", "stamp_wander_s"),),
            "receive times wandering about the clock line",
        ),
    },
)


@contextlib.contextmanager
def clock_wander_registered():
    """The new effect's two registrations, undone on leaving."""
    register_effect(ClockWander)
    register(CLOCK_WANDER)
    try:
        yield
    finally:
        unregister_spec(CLOCK_WANDER.name)
        EFFECTS.pop(ClockWander.name)


# --------------------------------------------------------------------------- the tests


def _recording(seed: int, effects: tuple = ()) -> pd.DataFrame:
    """An ingested static recording (acc/gyro at 100 Hz, magnetometer at 75 Hz, rows in
    receive order) rendered by the simulator with ``effects``."""
    truth = make_truth("paper", stream_rng(0, "truth"))
    streams = {"imu": (int(DURATION_S * 100) + 1, 100.0), "mag": (int(DURATION_S * 75) + 1, 75.0)}
    rendered = render_static(StaticTwin(truth, dict(SENSITIVITY), streams), seed, effects)
    frames = []
    for stream in rendered.values():
        data = {TIME: stream.t_s}
        for s, v in stream.values.items():
            data.update({c: v[:, j] for j, c in enumerate(SENSOR_COLUMNS[s])})
        frames.append(pd.DataFrame(data))
    return pd.concat(frames, ignore_index=True).sort_values(TIME, kind="stable", ignore_index=True)


def _diagnose(table: pd.DataFrame) -> dict:
    return diagnose_static(
        table, dataset="sim", calibration=None, sensitivity=SENSITIVITY, gravity_m_s2=9.81,
        settings=DiagnosisSettings(replicas=REPLICAS, seed=500),
    )  # fmt: skip


def test_the_new_effect_is_in_the_catalogue_and_the_scopes_tables():
    with clock_wander_registered():
        assert contract_violations() == []
        entry = catalogue()["clock_wander"]
        assert entry.estimated == {"static": (("ingest", "*", "stamp_wander_s"),)}
        assert set(entry.not_observable) == set(SCOPES) - {"static"}
        assert scope_library("static")["clock_wander"] is CLOCK_WANDER.scopes["static"]
        assert "clock_wander" in not_observable("rests")
    assert "clock_wander" not in EFFECTS and "clock_wander" not in catalogue()
    assert contract_violations() == []


def test_a_static_recording_with_the_new_effect_names_it():
    true = ClockWander(amplitude_s=0.004)
    with clock_wander_registered():
        d = _diagnose(_recording(5, (true,)))
        clean = _diagnose(_recording(6))
    assert d["explained"] == ["clock_wander"]
    assert d["verdict"]["sentence"].startswith("Effect clock_wander")
    wander = next(e for e in d["effects"] if e["name"] == "clock_wander")
    # the receive times hold no noise; the envelope (a running minimum over 10 s) follows a
    # sine of 120 s but for its crests, which it lowers by up to 1 - cos(2 pi 5 / 120) = 3.4 %
    assert wander["params"]["amplitude_s"] == pytest.approx(true.amplitude_s, rel=0.05)
    assert wander["heldout_shrink"] > 0.9
    assert not d["remaining"]["significant"]
    # without the effect its statistic stays in the null and nothing is named
    assert clean["explained"] == []
    assert next(e for e in clean["effects"] if e["name"] == "clock_wander")["accepted"] is False
