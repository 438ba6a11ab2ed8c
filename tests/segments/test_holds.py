"""Hand-held holds: the tremor-adaptive detector (Tedaldi 2014) behind the noise-derived one."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy import stats
from scipy.spatial.transform import Rotation, Slerp

from imucal.columns import ACC, GYR, TIME
from imucal.segments.detector import DetectorSettings, find_static_intervals
from imucal.segments.holds import MIN_HOLDS, find_holds
from imucal.segments.protocol import segment_poses
from imucal.segments.segmentation import segment_dataset
from imucal.sim.protocol import CUBE_UP_B

FS_HZ = 100.0
G = 9.81
ACC_NOISE = 0.02  # m/s^2 per axis and sample
GYR_NOISE = 0.005  # rad/s per axis and sample
INIT_S, HOLD_S, MOVE_S = 10.0, 3.0, 1.5
#: Tremor: per axis, sinusoids of TREMOR_AMP_RAD at 4-10 Hz (peak about 0.5 deg in all).
TREMOR_AMP_RAD = np.radians(0.17)
TREMOR_PER_AXIS = 3
F_MIN_HZ = 4.0


def render_session(tremor: bool, seed: int = 0):
    """Initial rest on a table, then the 12 cube poses held ``HOLD_S`` each (by hand when
    ``tremor``), smooth 1.5 s turns between them.

    Returns t (n,), acc (n, 3) m/s^2, gyr (n, 3) rad/s, the true specific force without tremor
    and noise (n, 3), and the rows of each true rest [(start, end)], the table rest first.
    """
    rng = np.random.default_rng(seed)
    ups = np.array(CUBE_UP_B, dtype=float)
    ups /= np.linalg.norm(ups, axis=1, keepdims=True)
    # orientation of each pose: body -> world, the body's `up` pointing to world z
    # the table rest tilted off every cube pose, so that the first turn is a turn
    poses = [Rotation.from_rotvec([0.3, 0.2, 0.0])] + [
        Rotation.align_vectors([[0, 0, 1]], [u])[0] for u in ups
    ]
    pieces, rests, n = [], [], 0
    for k, pose in enumerate(poses):
        m = round((INIT_S if k == 0 else HOLD_S) * FS_HZ)
        pieces.append(Rotation.concatenate([pose] * m))
        rests.append((n, n + m))
        n += m
        if k + 1 < len(poses):  # smoothstep turn to the next pose
            m = round(MOVE_S * FS_HZ)
            s = np.arange(1, m + 1) / (m + 1)
            slerp = Slerp([0, 1], Rotation.concatenate([pose, poses[k + 1]]))
            pieces.append(slerp(3 * s**2 - 2 * s**3))
            n += m
    orientation = Rotation.concatenate(pieces)
    t = np.arange(n) / FS_HZ
    if tremor:  # after the table rest, the hand's wobble about every body axis
        theta = np.zeros((n, 3))
        for axis in range(3):
            for _ in range(TREMOR_PER_AXIS):
                f = rng.uniform(F_MIN_HZ, 10.0)
                theta[:, axis] += TREMOR_AMP_RAD * np.sin(2 * np.pi * f * t + rng.uniform(0, 6.3))
        theta[: rests[0][1]] = 0.0
        held = orientation * Rotation.from_rotvec(theta)
    else:
        held = orientation
    gravity_world = np.array([0.0, 0.0, G])
    true_force = orientation.inv().apply(gravity_world)
    force = held.inv().apply(gravity_world)
    # body rate between consecutive samples
    step = (held[:-1].inv() * held[1:]).as_rotvec() * FS_HZ
    rate = np.vstack([step, step[-1:]])
    acc = force + rng.normal(0, ACC_NOISE, (n, 3))
    gyr = rate + rng.normal(0, GYR_NOISE, (n, 3))
    return t, acc, gyr, true_force, rests


@pytest.fixture(scope="module")
def hand_held():
    return render_session(tremor=True)


def test_hand_held_holds_are_missed_by_the_noise_threshold_and_found_by_the_adaptive_one(
    hand_held,
):
    t, acc, gyr, true_force, rests = hand_held
    settings = DetectorSettings()
    noise_only = find_static_intervals(t, acc, gyr, settings).intervals
    assert len(noise_only) < MIN_HOLDS

    poses = segment_poses("poses", t, acc, gyr, settings)
    assert len(poses) == len(rests)
    note = poses.attrs["notes"]["poses"]
    assert "tremor-adaptive" in note and "threshold" in note
    window = round(settings.window_s * FS_HZ)
    for (a, b), row in zip(rests, poses.itertuples()):
        # inside the true rest, give or take one window at its ends
        assert a - window <= row.start_index and row.end_index <= b + window
        assert row.end_index - row.start_index >= settings.min_static_s * FS_HZ
        rows = slice(row.start_index, row.end_index)
        n = row.end_index - row.start_index
        # tremor: the mean of a sinusoid over T s is at most amp / (pi f T); second order
        # g theta^2 / 2; noise: 4 sigma of a mean of n samples
        theta_mean = TREMOR_PER_AXIS * TREMOR_AMP_RAD / (np.pi * F_MIN_HZ * n / FS_HZ)
        theta_peak = TREMOR_PER_AXIS * TREMOR_AMP_RAD * np.sqrt(3)
        tol = np.sqrt(2) * G * theta_mean + G * theta_peak**2 / 2 + 4 * ACC_NOISE / np.sqrt(n)
        error = acc[rows].mean(axis=0) - true_force[rows].mean(axis=0)
        assert np.abs(error).max() < tol


def test_adaptive_threshold_is_a_multiple_of_the_table_rest_variance(hand_held):
    t, acc, _, _, rests = hand_held
    holds = find_holds(t, acc, DetectorSettings(), base_interval=rests[0])
    # base: total variance of the white noise on the table, 3 sigma^2 (chi2 median ~ mean)
    assert holds.base_var_m2_s4 == pytest.approx(3 * ACC_NOISE**2, rel=0.1)
    assert holds.multiple is not None and len(holds.intervals) == len(rests)
    chosen = next(tr for tr in holds.trials if tr.multiple == holds.multiple)
    best = min(
        (tr for tr in holds.trials if np.isfinite(tr.residual_m_s2)),
        key=lambda tr: tr.residual_m_s2,
    )
    # the chosen residual is not significantly above the smallest (F test at 5 %)
    limit = stats.f.ppf(0.95, chosen.n_holds - 9, best.n_holds - 9)
    assert (chosen.residual_m_s2 / best.residual_m_s2) ** 2 <= limit
    assert chosen.n_holds >= best.n_holds


def test_table_top_session_keeps_the_noise_derived_detector():
    t, acc, gyr, _, rests = render_session(tremor=False, seed=1)
    settings = DetectorSettings()
    noise_only = find_static_intervals(t, acc, gyr, settings).intervals
    assert len(noise_only) == len(rests)
    poses = segment_poses("poses", t, acc, gyr, settings)
    assert poses.attrs["notes"] == {}
    assert list(zip(poses["start_index"], poses["end_index"])) == noise_only


def test_the_notes_reach_the_segments_table(hand_held):
    t, acc, gyr, _, rests = hand_held
    table = pd.DataFrame({TIME: t, **dict(zip(ACC, acc.T)), **dict(zip(GYR, gyr.T))})
    segments = segment_dataset({"poses": table}, fallback=True)
    assert len(segments) == len(rests)
    assert "tremor-adaptive" in segments.attrs["notes"]["poses"]


def test_base_interval_is_checked(hand_held):
    t, acc, *_ = hand_held
    with pytest.raises(ValueError, match="expected at least one window"):
        find_holds(t, acc, DetectorSettings(), base_interval=(0, 10))
    with pytest.raises(ValueError, match="expected positive numbers"):
        find_holds(t, acc, DetectorSettings(), multiples=(0,))
