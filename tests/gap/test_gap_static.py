"""The gap diagnosis of partial sessions on their static recording (imucal.gap.static).

Simulated static sessions are rendered by the simulator (the static ``hold`` at 100 Hz acc/gyro
and 75 Hz magnetometer, a temperature channel) with or without a known effect, written as an
ingested table (acc/gyro rows and magnetometer rows apart, as a multi-stream reader gives them)
and diagnosed from that table alone.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from imucal.columns import SENSOR_COLUMNS, TIME
from imucal.gap import DiagnosisSettings
from imucal.gap.composite import diagnose_partial_session
from imucal.gap.static import diagnose_static
from imucal.gap.streams import split_streams
from imucal.gap.twin import StaticTwin, render_static
from imucal.sim import make_effect, make_truth
from imucal.sim.effects import stream_rng
from imucal.sim.session import SENSITIVITY

DURATION_S = 300.0
REPLICAS = 12


def _session(seed: int, effects: tuple = ()) -> pd.DataFrame:
    """An ingested static recording rendered by the simulator, rows in receive order."""
    truth = make_truth("paper", stream_rng(0, "truth"))
    streams = {"imu": (int(DURATION_S * 100) + 1, 100.0), "mag": (int(DURATION_S * 75) + 1, 75.0)}
    # a slow cooling of 0.3 K, like a module on a desk, carried by the temperature channel
    t = np.linspace(0.0, DURATION_S, 50)
    temperature = (t, 25.4 - 0.3 * (1 - np.exp(-t / 200.0)))
    twin = StaticTwin(truth, dict(SENSITIVITY), streams, temperature)
    rendered = render_static(twin, seed, effects)
    frames = []
    for stream in rendered.values():
        data = {TIME: stream.t_s}
        for s, v in stream.values.items():
            data.update({c: v[:, j] for j, c in enumerate(SENSOR_COLUMNS[s])})
        if stream.temperature_c is not None:
            data["temp_c"] = stream.temperature_c
        frames.append(pd.DataFrame(data))
    return pd.concat(frames, ignore_index=True).sort_values(TIME, kind="stable", ignore_index=True)


def _diagnose(table: pd.DataFrame) -> dict:
    return diagnose_static(
        table, dataset="sim", calibration=None, sensitivity=SENSITIVITY, gravity_m_s2=9.81,
        settings=DiagnosisSettings(replicas=REPLICAS, seed=500),
    )  # fmt: skip


def test_streams_are_split_at_their_own_rates():
    streams = split_streams(_session(1))
    assert set(streams) == {"imu", "mag"}
    assert streams["imu"].rate_hz == pytest.approx(100.0, rel=1e-9)
    assert streams["mag"].rate_hz == pytest.approx(75.0, rel=1e-9)
    assert streams["imu"].temperature_c is not None and streams["mag"].temperature_c is None


@pytest.mark.parametrize("seed", [3, 4])
def test_no_effect_explains_nothing(seed):
    d = _diagnose(_session(seed))
    assert d["explained"] == []
    # the total gap of a clean session is a draw from the null: well below 3x its 95th percentile
    assert d["gap"]["total"] < 3 * d["gap"]["null_p95"]


def test_timing_jitter_is_found_estimated_and_explained():
    true_std = 0.004
    d = _diagnose(_session(5, (make_effect("timing_jitter", std_s=true_std),)))
    assert d["gap"]["significant"]
    assert {loc["statistic"] for loc in d["locations"]} >= {"stamp_scatter_s", "burst_fraction"}
    assert d["explained"][:1] == ["timing_jitter"]
    jitter = next(e for e in d["effects"] if e["name"] == "timing_jitter")
    # the estimator inverts the model's mean latency over ~50k samples: a few % at most
    assert jitter["params"]["std_s"] == pytest.approx(true_std, rel=0.1)
    assert jitter["heldout_shrink"] > 0.9
    assert not d["remaining"]["significant"]


def test_temperature_drift_is_found_on_the_temperature_channel():
    # a 4 K warm-up with a gyro bias drift of its own on each axis, of either sign, up to
    # 3e-4 rad/s/K (0.017 deg/s/K)
    k = np.array([3e-4, -2e-4, 1e-4])
    effect = make_effect(
        "temperature_drift", start_c=25.0, rise_c=4.0, tau_s=100.0, acc_per_k=0.0,
        gyr_per_k=k, acc_scale_per_k=0.0, gyr_scale_per_k=0.0,
    )  # fmt: skip
    d = _diagnose(_session(6, (effect,)))
    assert d["gap"]["significant"]
    assert any(
        loc["statistic"] == "temp_slope" and loc["sensor"] == "gyr" for loc in d["locations"]
    )
    assert d["explained"][:1] == ["temperature_drift"]
    drift = next(e for e in d["effects"] if e["name"] == "temperature_drift")
    np.testing.assert_allclose(drift["params"]["gyr_per_k"], k, atol=0.2 * 3e-4)
    assert drift["heldout_shrink"] > 0.7


def test_a_session_without_static_recording_says_why():
    d = diagnose_partial_session(
        None, dataset="x", calibration=None, sensitivity={}, gravity_m_s2=9.81,
        settings=DiagnosisSettings(replicas=5, seed=0, crn_seeds=2),
    )  # fmt: skip
    assert d["explained"] == [] and d["locations"] == [] and d["scope"] == "none"
    assert "neither a static recording nor a recording with an orientation reference" in d["reason"]


def test_too_few_replicas_are_refused():
    with pytest.raises(ValueError, match="at least 5 replicas"):
        DiagnosisSettings(replicas=3)
    with pytest.raises(ValueError, match=r"unknown diagnosis settings \['replica'\]"):
        DiagnosisSettings.from_config({"replica": 20})
