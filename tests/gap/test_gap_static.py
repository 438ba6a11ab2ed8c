"""The gap diagnosis of partial sessions on their static recording (imucal.gap.static).

Simulated static sessions are rendered by the simulator (the static ``hold`` at 100 Hz acc/gyro
and 75 Hz magnetometer, a temperature channel) with or without a known effect, written as an
ingested table (acc/gyro rows and magnetometer rows apart, as a multi-stream reader gives them)
and diagnosed from that table alone.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from imucal.columns import SEGMENT_COLUMNS, SENSOR_COLUMNS, SENSORS, TIME
from imucal.gap import DiagnosisSettings
from imucal.gap.composite import diagnose_partial_session, rest_as_static
from imucal.gap.library import scope_library
from imucal.gap.static import diagnose_static
from imucal.gap.statictwin import StaticTwin, build_static_twin, render_static
from imucal.gap.streams import split_streams, temperature_slopes
from imucal.sim import make_effect, make_truth
from imucal.sim.effects import stream_rng
from imucal.sim.session import SENSITIVITY

DURATION_S = 300.0
REPLICAS = 12


def static_session(
    seed: int, effects: tuple = (), noise_counts: float | None = None
) -> pd.DataFrame:
    """An ingested static recording rendered by the simulator, rows in receive order (white
    noise of ``noise_counts`` quantisation steps when given, else the paper's)."""
    truth = make_truth("paper", stream_rng(0, "truth"))
    if noise_counts is not None:
        truth = replace(truth, noise={s: noise_counts * SENSITIVITY[s] for s in SENSORS})
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


def diagnose_sim(table: pd.DataFrame) -> dict:
    return diagnose_static(
        table, dataset="sim", calibration=None, sensitivity=SENSITIVITY, gravity_m_s2=9.81,
        settings=DiagnosisSettings(replicas=REPLICAS, seed=500),
    )  # fmt: skip


def test_streams_are_split_at_their_own_rates():
    streams = split_streams(static_session(1))
    assert set(streams) == {"imu", "mag"}
    assert streams["imu"].rate_hz == pytest.approx(100.0, rel=1e-9)
    assert streams["mag"].rate_hz == pytest.approx(75.0, rel=1e-9)
    # the magnetometer's rows carry no reading of the channel: it is interpolated to them by
    # receive time from the acc/gyro rows
    imu, mag = streams["imu"], streams["mag"]
    assert imu.temperature_c is not None and mag.temperature_c is not None
    np.testing.assert_allclose(
        mag.temperature_c, np.interp(mag.t_s, imu.t_s, imu.temperature_c), rtol=0, atol=1e-12
    )


@pytest.mark.parametrize("seed", [3, 4])
def test_no_effect_explains_nothing(seed):
    d = diagnose_sim(static_session(seed))
    assert d["explained"] == []
    # the total gap of a clean session is a draw from the null: well below 3x its 95th percentile
    assert d["gap"]["total"] < 3 * d["gap"]["null_p95"]
    assert d["verdict"]["outcome"] in ("nothing beyond the model", "twin lacks")
    assert d["verdict"]["effects"] == []


def test_a_recording_with_noise_below_one_count_gets_a_null_with_spread():
    """White noise of 0.15 counts rounded: the readings flip between counts now and then. The
    twin measures that noise under the rounding (subtracting step^2 / 12 called it 0, every
    replica read the same counts and the null's 95th percentile was 0)."""
    d = diagnose_sim(static_session(8, noise_counts=0.15))
    assert d["gap"]["null_p95"] > 0
    white = d["twin"]["noise_process"]["gyr"]["white"]
    # an axis whose reading never flips has no noise to find; the others do
    assert max(white) > 0.1 * SENSITIVITY["gyr"]
    assert d["explained"] == [] and d["verdict"]["effects"] == []


def test_timing_jitter_is_found_estimated_and_explained():
    true_std = 0.004
    d = diagnose_sim(static_session(5, (make_effect("timing_jitter", std_s=true_std),)))
    assert d["gap"]["significant"]
    assert {loc["statistic"] for loc in d["locations"]} >= {"stamp_scatter_s", "burst_fraction"}
    assert d["explained"][:1] == ["timing_jitter"]
    assert d["verdict"]["outcome"] == "effect"
    assert d["verdict"]["sentence"].startswith("Effect timing_jitter (acquisition), shrink ")
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
    d = diagnose_sim(static_session(6, (effect,)))
    assert d["gap"]["significant"]
    assert any(
        loc["statistic"] == "temp_slope" and loc["sensor"] == "gyr" for loc in d["locations"]
    )
    # the drift alone: the twin's noise is fitted with the drift taken out, so a bias wander
    # (bias_instability) is not named beside it
    assert d["explained"] == ["temperature_drift"]
    drift = next(e for e in d["effects"] if e["name"] == "temperature_drift")
    np.testing.assert_allclose(drift["params"]["gyr_per_k"], k, atol=0.2 * 3e-4)
    assert drift["heldout_shrink"] > 0.7


def test_a_full_protocol_session_keeps_a_wandering_bias_an_effect():
    """A gyro bias random walk of 1.2e-4 rad/s/sqrt(s) (the stress set's): over 300 s it
    wanders by about 2e-3 rad/s, against 1.5e-3 rad/s of white noise per sample. A partial
    session's twin takes the wander into its own noise (the sensor as it is), so nothing is
    named; the static recording of a full-protocol session whose chain stopped is diagnosed
    with the full protocol's twin, white noise only, and the wander is bias_instability."""
    effect = make_effect("bias_instability", gyr_rw=1.2e-4, gyr_gm=1e-4, acc_rw=0.0, acc_gm=0.0)
    table = static_session(8, (effect,))
    common = dict(
        dataset="sim", calibration=None, sensitivity=SENSITIVITY, gravity_m_s2=9.81,
        settings=DiagnosisSettings(replicas=REPLICAS, seed=500),
    )  # fmt: skip
    d = diagnose_static(table, wander=False, **common)
    assert d["explained"] == ["bias_instability"]
    assert any("white noise per axis" in n for n in d["twin"]["notes"])
    clean = diagnose_static(static_session(9), wander=False, **common)
    assert clean["explained"] == []


def test_a_drift_is_rendered_about_the_recordings_level():
    """The twin reads the recording's mean reading, which holds its drift at its mean
    temperature; the estimated drift, rendered from its ``start_c``, varies about that level
    instead of moving it a second time (which pushed a large drift off the int16 range of a
    step estimated from the readings, where the replica clipped)."""
    k = np.array([3e-4, -2e-4, 1e-4])
    effect = make_effect(
        "temperature_drift", start_c=25.0, rise_c=4.0, tau_s=100.0, acc_per_k=0.0,
        gyr_per_k=k, acc_scale_per_k=0.0, gyr_scale_per_k=0.0,
    )  # fmt: skip
    streams = split_streams(static_session(6, (effect,)))
    twin = build_static_twin(streams, None, {}, 9.81)  # the step estimated from the readings
    model = scope_library("static")["temperature_drift"]
    drift = model.simulator_effect(model.estimate(streams, None).params)
    step = twin.sensitivity["gyr"]
    for seed in (0, 1):
        rendered = render_static(twin, seed, (drift,))["imu"]
        clean = render_static(twin, seed)["imu"]
        # the same seed draws the same noise: the means differ by the drift's rounding only
        # (counted twice, by k times the mean warming of 2.7 K above start_c: 1-3 counts)
        shift = rendered.values["gyr"].mean(axis=0) - clean.values["gyr"].mean(axis=0)
        assert np.all(np.abs(shift) < 0.1 * step)
        # the recording's slopes, within 3x the spread of a difference of two noisy slopes
        # (sqrt(2) x 1.5e-5, the largest spread over clean replicas)
        np.testing.assert_allclose(
            temperature_slopes(rendered)["gyr"], temperature_slopes(streams["imu"])["gyr"],
            atol=6e-5,
        )  # fmt: skip


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


def test_the_longest_rest_stands_in_for_a_missing_static_recording():
    """Two recordings with rests of 30 s and 45 s: the 45 s one is cut out as the static
    recording; with a 60 s minimum none is, and the reason gives the longest."""
    rest = static_session(9).iloc[: int(50 * 175)]  # the first 50 s (100 + 75 rows a second)
    tables = {"a": rest, "b": rest}
    rows = [
        {"recording": r, "label": label, "kind": "static", "start_s": 1.0, "end_s": 1.0 + d,
         "start_index": 0, "end_index": 0, "axis": "", "rate_dps": np.nan, "sense": 0,
         "turns": np.nan, "up": "", "angle_deg": np.nan}
        for r, label, d in (("a", "s01", 30.0), ("b", "s02", 45.0))
    ]  # fmt: skip
    segments = pd.DataFrame(rows, columns=list(SEGMENT_COLUMNS))
    table, source = rest_as_static(tables, segments)
    assert source == "the rest s02 of recording b (45.0 s)"
    t = table[TIME].to_numpy()
    assert t.min() >= 1.0 and t.max() <= 46.0 and t.max() - t.min() > 44.9
    none, why = rest_as_static(tables, segments, min_duration_s=60.0)
    assert none is None and why.startswith("the longest rest is 45.0 s; a rest is scored from 60 s")
