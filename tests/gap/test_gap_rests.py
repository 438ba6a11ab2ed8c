"""The gap diagnosis of a partial session on its pooled short rests (imucal.gap.rests).

A simulated session is a hand-placed multi-position session: eight rests of 3.5-7 s at
different orientations (acc/gyro at 100 Hz, the paper's noise, rounded to the paper's counts),
written as one ingested recording with the motions between the rests left out, and a segments
table that declares the rests. It is diagnosed from that table alone, as the workflow does.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation

from imucal import errormodel
from imucal.columns import SEGMENT_COLUMNS, SENSOR_COLUMNS, TIME
from imucal.gap import DiagnosisSettings
from imucal.gap.composite import diagnose_rests_scope, partial_scope
from imucal.gap.fieldfit import moving_white
from imucal.gap.rests import pooled_white, session_rests
from imucal.gap.statictwin import StaticTwin, render_static
from imucal.noise.process import quantised_variance
from imucal.sim import make_effect, make_truth
from imucal.sim.effects import stream_rng
from imucal.sim.session import SENSITIVITY

REPLICAS = 12
RATE_HZ = 100.0
DURATIONS_S = (5.0, 3.5, 7.0, 4.0, 6.0, 4.5, 5.5, 3.5)


def _session(seed: int, effects: tuple = ()) -> tuple[dict, pd.DataFrame]:
    """One recording of eight rests 10 s apart (the motions between them left out) and its
    segments table; the rests at random orientations and gyro biases of a few counts."""
    truth = make_truth("paper", stream_rng(0, "truth"))
    rng = np.random.default_rng(seed)
    frames, rows, start = [], [], 0.0
    index = 0
    for k, duration in enumerate(DURATIONS_S):
        up = rng.normal(size=3)
        level = {"acc": 9.81 * up / np.linalg.norm(up), "gyr": rng.normal(0.0, 4e-3, 3)}
        n = int(duration * RATE_HZ) + 1
        twin = StaticTwin(truth, dict(SENSITIVITY), {"imu": (n, RATE_HZ)}, level=level)
        stream = render_static(twin, seed * 100 + k, effects)["imu"]
        data = {TIME: start + stream.t_s}
        for s, v in stream.values.items():
            data.update({c: v[:, j] for j, c in enumerate(SENSOR_COLUMNS[s])})
        frames.append(pd.DataFrame(data))
        rows.append({"recording": "poses", "label": f"s{k:02d}", "kind": "static",
                     "start_s": start, "end_s": start + stream.t_s[-1], "start_index": index,
                     "end_index": index + n})  # fmt: skip
        index += n
        start += duration + 10.0
    segments = pd.DataFrame(rows).reindex(columns=list(SEGMENT_COLUMNS))
    return {"poses": pd.concat(frames, ignore_index=True)}, segments


def _diagnose(tables: dict, segments: pd.DataFrame) -> dict:
    return diagnose_rests_scope(
        tables, segments, dataset="sim", calibration=None, sensitivity=SENSITIVITY,
        gravity_m_s2=9.81, settings=DiagnosisSettings(replicas=REPLICAS, seed=700),
    )  # fmt: skip


def test_the_scope_is_chosen_from_what_the_session_has():
    assert partial_scope(static=True, references=True, poses=False) == "static+reference"
    assert partial_scope(static=False, references=True, poses=True) == "reference"
    assert partial_scope(static=True, references=False, poses=True) == "static"
    assert partial_scope(static=False, references=False, poses=True) == "poses"
    assert partial_scope(static=False, references=False, poses=False) == "rests"


def test_rests_shorter_than_the_minimum_are_left_out():
    tables, segments = _session(1)
    rests, source = session_rests(tables, segments, min_duration_s=4.0)
    assert len(rests) == 6
    assert source.startswith("6 rests of 4.0-7.0 s") and "2 shorter ones left out" in source
    none, why = session_rests(tables, segments, min_duration_s=8.0)
    assert none == {} and why == "none of the 8 rests found is 8 s long with 100 samples"


def test_pooled_white_noise_below_one_count_is_found_at_each_rests_level():
    """0.3 counts of white noise about levels at different offsets within a count: the
    variance of the rounded readings differs from rest to rest; the pooled std is found
    within the sampling error of 8 x 500 differences per axis."""
    rng = np.random.default_rng(4)
    step, std = 1e-3, 0.3e-3
    parts = []
    for _ in range(8):
        level = rng.uniform(-0.05, 0.05, 3)
        parts.append(step * np.round((level + rng.normal(0.0, std, (501, 3))) / step))
    white = pooled_white(parts, step)
    # the rounded variance's relative error over 4000 differences (~ sqrt(2/4000) per axis),
    # carried to the std through the local slope of the rounding
    assert quantised_variance(std, step) > 0
    np.testing.assert_allclose(white, std, rtol=0.12)


@pytest.mark.parametrize("seed", [3, 4])
def test_a_clean_short_rest_session_gets_a_null_and_nothing_named(seed):
    d = _diagnose(*_session(seed))
    assert d["scope"] == "rests"
    assert d["gap"]["null_p95"] > 0
    assert d["explained"] == []
    assert d["verdict"]["effects"] == []
    assert d["gap"]["total"] < 3 * d["gap"]["null_p95"]
    assert "timing_jitter" not in d["not_observable"]
    assert "bias_instability" in d["not_observable"]
    stats = {loc["statistic"] for loc in d["all_locations"]}
    assert stats >= {"rest_noise", "rest_still_fraction", "rest_adev_excess",
                     "rest_trend_per_s", "stamp_scatter_s", "burst_fraction"}  # fmt: skip


def test_a_receive_latency_in_the_rests_is_named():
    """Exponential receive latency with queueing, 4 ms mean, at 100 Hz: the rests' receive
    times show it; it is explained, its estimate within 10 % (the static check's tolerance)."""
    true_std = 0.004
    d = _diagnose(*_session(5, (make_effect("timing_jitter", std_s=true_std),)))
    assert d["gap"]["significant"]
    assert "stamp_scatter_s" in {loc["statistic"] for loc in d["locations"]}
    assert d["explained"] == ["timing_jitter"]
    effect = next(e for e in d["effects"] if e["name"] == "timing_jitter")
    assert effect["params"]["std_s"] == pytest.approx(true_std, rel=0.1)
    assert effect["heldout_shrink"] > 0.9
    assert d["verdict"]["outcome"] == "effect"
    assert d["gap"]["null_p95"] > 0


def test_a_session_without_rests_says_why():
    tables, segments = _session(6)
    d = _diagnose(tables, segments.iloc[:0])
    assert d["scope"] == "none"
    assert d["static_source"].startswith("no rest was found; a rest is scored from 40 s")
    assert d["static_source"].endswith("field fit: the session has no magnetometer calibration")


def _tumble(seed: int, slow_field: float = 0.0) -> tuple[dict, dict]:
    """A magnetometer turned by hand for 200 s at 50 Hz without a rest (a smooth random
    rotation of about 1 rad/s), through a hard- and soft-iron calibration, white noise of 2.5e-3
    of the field per axis, rounded to 5e-4; with ``slow_field`` the field's norm varies by that
    fraction over 20 s (an ambient field that changes)."""
    rng = np.random.default_rng(seed)
    rate, n = 50.0, 10001
    t = np.arange(n) / rate
    omega = np.cumsum(rng.normal(0.0, 0.05, (n, 3)), axis=0)
    omega = 1.0 * omega / np.sqrt(np.mean(np.sum(omega**2, axis=1)))
    rot = Rotation.identity()
    directions = np.empty((n, 3))
    field = np.array([0.6, 0.0, -0.8])
    for k in range(n):
        directions[k] = rot.inv().apply(field)
        rot = rot * Rotation.from_rotvec(omega[k] / rate)
    norm = 1.0 + slow_field * np.sin(2 * np.pi * t / 20.0)
    matrix = np.array([[1.8, 0.05, -0.02], [0.0, 2.2, 0.04], [0.0, 0.0, 1.6]])
    bias = np.array([0.3, -0.1, 0.2])
    raw = errormodel.invert(matrix, bias, directions * norm[:, None])
    raw = 5e-4 * np.round((raw + rng.normal(0.0, 2.5e-3, raw.shape)) / 5e-4)
    table = pd.DataFrame({TIME: t, **{c: raw[:, j] for j, c in enumerate(SENSOR_COLUMNS["mag"])}})
    calibration = {"mag": {"matrix": matrix.tolist(), "bias": bias.tolist(), "method": "sim"}}
    return {"tumble": table}, calibration


def test_a_magnetometer_tumble_without_rests_gets_the_null_of_its_field_fit():
    """No rest at all: the fit residual is scored. The noise from the second differences is
    found within 5 % (the motion's second difference is about 1e-4 of the field against
    noise of 2.5e-3 x 1.6-2.2 per reading); a clean tumble leaves nothing in the gap, a field
    whose norm varies by 2 % is in the gap at the residual's slow part and no effect is named."""
    tables, calibration = _tumble(8)
    empty = pd.DataFrame(columns=list(SEGMENT_COLUMNS))
    raw = tables["tumble"][list(SENSOR_COLUMNS["mag"])].to_numpy()
    white = np.sqrt(np.maximum(moving_white(raw) ** 2 - (5e-4) ** 2 / 12, 0.0))
    np.testing.assert_allclose(white, 2.5e-3, rtol=0.05)
    kw = dict(dataset="sim", calibration=calibration, sensitivity={"mag": 5e-4},
              gravity_m_s2=9.81, settings=DiagnosisSettings(replicas=REPLICAS, seed=700))  # fmt: skip
    clean = diagnose_rests_scope(tables, empty, **kw)
    assert clean["scope"] == "field_fit"
    assert clean["gap"]["null_p95"] > 0
    assert clean["verdict"]["outcome"] == "nothing beyond the model"
    varying = diagnose_rests_scope(_tumble(8, slow_field=0.02)[0], empty, **kw)
    assert "fit_resid_slow" in {loc["statistic"] for loc in varying["locations"]}
    assert varying["verdict"]["outcome"] == "twin lacks" and varying["explained"] == []
