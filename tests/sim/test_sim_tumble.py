"""A module tumbled by hand (imucal.sim.tumble): its poses and pauses as planned, the hand's
tremor on the pauses only, and the hand's sway in translation seen by the accelerometer alone."""

from __future__ import annotations

import numpy as np
import pytest

from imucal import errormodel
from imucal.columns import ACC, GYR, TIME
from imucal.sim import TumbleConfig, evaluate_motion, make_effect, make_truth, simulate_tumble
from imucal.sim.effects import stream_rng


@pytest.fixture(scope="module")
def truth():
    return make_truth("random", stream_rng(3, "truth"))


def _calibrated(session, columns, sensor):
    frame = session.si_frame()
    cal = session.truth.calibration.sensor(sensor)
    return errormodel.apply(cal.matrix, cal.bias, frame[list(columns)].to_numpy(dtype=float))


def test_the_plan_holds_its_poses_for_the_pauses_it_states(truth):
    config = TumbleConfig(poses=26, hold_s=(0.5, 0.9))
    session = simulate_tumble(truth, 3, config)
    pauses = session.pauses_s()
    assert len(pauses) == 26
    assert np.all((pauses[:, 1] - pauses[:, 0] >= 0.5) & (pauses[:, 1] - pauses[:, 0] <= 0.9))
    rest = session.plan.segments[0]
    assert (rest.kind, rest.start_s, rest.end_s) == ("static", 0.0, config.rest_s)
    # at rest in every pause: the calibrated accelerometer reads gravity in the planned pose
    t = session.si_frame()[TIME].to_numpy()
    acc = _calibrated(session, ACC, "acc")
    gyr = _calibrated(session, GYR, "gyr")
    for start, end in pauses:
        inside = (t >= start) & (t < end)
        state = evaluate_motion(session.plan.motion, t[inside])
        expected = state.rotation.apply(truth.world.specific_force, inverse=True)
        assert np.abs(acc[inside] - expected).mean() < 0.05  # the 0.02 m/s^2 noise
        assert np.abs(gyr[inside]).mean() < 0.005  # still: the 0.0015 rad/s noise
    # the poses differ: many distinct gravity directions
    ups = np.array([acc[(t >= a) & (t < b)].mean(axis=0) for a, b in pauses])
    ups /= np.linalg.norm(ups, axis=1, keepdims=True)
    assert np.percentile(np.degrees(np.arccos(np.clip(ups @ ups.T, -1, 1))), 90) > 90


def test_the_hands_sway_moves_the_specific_force_in_the_pauses_only(truth):
    still = simulate_tumble(truth, 3, effects=(make_effect("hand_tremor"),))
    swaying = simulate_tumble(truth, 3, effects=(make_effect("hand_tremor", sway_mm=8.0),))
    t = still.si_frame()[TIME].to_numpy()
    # same rotation (the translation draws from its own stream), so the gyroscope is the same
    np.testing.assert_array_equal(still.frame()[list(GYR)], swaying.frame()[list(GYR)])
    extra = _calibrated(swaying, ACC, "acc") - _calibrated(still, ACC, "acc")
    held = np.zeros(t.size, dtype=bool)
    for start, end in still.pauses_s():
        held |= (t >= start) & (t < end)
    step = np.linalg.norm(swaying.sensitivity["acc"] * np.ones(3))  # a count's rounding
    assert np.abs(extra[~held]).max() <= 2 * step
    # two sinusoids of 8 mm at up to 0.8 Hz per axis under an envelope e (ramps of at least
    # 0.25 s in pauses of 0.5 s: |e'| <= 2 / ramp, |e''| <= 2 pi / ramp^2): at most
    # 2 A (w^2 + 2 |e'| w + |e''|) per axis; on average far above the rounding
    w, ramp = 2 * np.pi * 0.8, 0.25
    bound = 2 * 8e-3 * (w**2 + 2 * (2 / ramp) * w + 2 * np.pi / ramp**2)
    assert np.abs(extra[held]).max() < np.sqrt(3) * bound
    assert np.sqrt(np.mean(extra[held] ** 2)) > 10 * step
