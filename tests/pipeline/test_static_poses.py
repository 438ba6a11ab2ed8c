"""Static-pose recordings: what the cube fit can learn from their orientations, short pauses."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import partial_session, z_limit

from imucal.columns import ACC, GYR, TIME
from imucal.fits import gyroscope, orientations
from imucal.ingest import ingest_recording
from imucal.io.dataset import read_dataset
from imucal.pipeline import partial
from imucal.segments.segmentation import segment_dataset
from imucal.segments.table import segment_row, segments_frame
from imucal.sim.protocol import CUBE_UP_B

G = 9.81
ACC_NOISE = 0.02  # m/s^2
GYR_NOISE = 2e-3  # rad/s
GYR_BIAS = np.array([0.03, -0.01, 0.005])  # rad/s


def three_pose_session(rng: np.random.Generator) -> tuple[pd.DataFrame, pd.DataFrame, int]:
    """A 1 Hz logger left in three one-sided poses (-z, -x, -y), each for 3000 s, with 30
    handling pauses of 2-40 samples at the same orientations between them (a few degrees off);
    a miscalibrated accelerometer. Returns the table, its static segments and the number of
    pauses shorter than the gyro bias's minimum."""
    upper = np.array([[1.03, 0.01, -0.02], [0.0, 0.97, 0.015], [0.0, 0.0, 1.05]])
    bias = np.array([0.2, -0.3, 0.15])
    pieces, rows, start, short = [], [], 0, 0
    plan = []
    for up in ([0, 0, -1], [-1, 0, 0], [0, -1, 0]):
        plan.append((np.array(up, float), 3000))
        for _ in range(10):
            plan.append((np.array(up, float) + rng.normal(0, 0.05, 3), int(rng.integers(2, 41))))
    t_all = []
    for k, (up, n) in enumerate(plan):
        up = up / np.linalg.norm(up)
        reading = np.linalg.solve(upper, G * up) + bias
        acc = reading + ACC_NOISE * rng.standard_normal((n, 3))
        gyr = GYR_BIAS + GYR_NOISE * rng.standard_normal((n, 3))
        moving = 5  # samples of handling between pauses (not a segment)
        acc = np.vstack([acc, rng.normal(0, 3, (moving, 3))])
        gyr = np.vstack([gyr, rng.normal(0, 1, (moving, 3))])
        pieces.append(np.column_stack([acc, gyr]))
        rows.append((f"s{k:02d}", start, start + n))
        short += n < gyroscope.MIN_STATIC_SAMPLES
        start += n + moving
    data = np.vstack(pieces)
    t_all = np.arange(len(data), dtype=float)
    table = pd.DataFrame({TIME: t_all, **dict(zip(ACC + GYR, data.T))})
    segments = segments_frame(
        [segment_row("poses", label, "static", t_all, a, b) for label, a, b in rows]
    )
    return table, segments, short


def test_three_one_sided_poses_refuse_the_cube_fit_and_say_what_it_needs():
    rng = np.random.default_rng(31)
    table, segments, short = three_pose_session(rng)
    assert len(segments) == 33 and short > 0  # more segments than the 9 unknowns
    outcomes = {
        o.name: o for o in partial.run_stages(partial_session({"poses": table}, segments, G))
    }
    cube = outcomes["acc_cube"]
    assert cube.status == "skipped"
    assert "3 distinct orientation(s) (-z, -x, -y;" in cube.reason
    assert "rank 3 of the 9 parameters" in cube.reason
    assert "one-sided axes: x (only -), y (only -), z (only -)" in cube.reason
    assert "needs at least 9 distinct orientations spanning both signs of each axis" in cube.reason
    # the gyro bias from the long rests, the pauses shorter than its minimum left out, counted
    bias = outcomes["gyr_bias"]
    assert bias.status == "run"
    assert bias.artifact["short_left_out"] == short
    assert bias.artifact["n_segments"] == len(segments) - short
    estimate = np.asarray(bias.artifact["bias_ls_rad_s"])
    std = np.asarray(bias.artifact["std_ls_rad_s"])
    assert np.all(np.abs(estimate - GYR_BIAS) < z_limit(3) * std)


def test_only_short_pauses_skip_the_gyro_bias_with_the_count_instead_of_stopping():
    pieces = [np.zeros((k, 3)) for k in (2, 6, 9)]
    kept, keep, left_out = gyroscope.usable_static_segments(pieces)
    assert kept == [] and not keep.any()
    assert left_out == {"short_left_out": 3, "short_left_out_samples": 17, "min_static_samples": 10}
    rng = np.random.default_rng(5)
    table, segments, _ = three_pose_session(rng)
    segments = segments[segments["end_index"] - segments["start_index"] < 10]
    outcomes = {
        o.name: o for o in partial.run_stages(partial_session({"poses": table}, segments, G))
    }
    assert outcomes["gyr_bias"].status == "skipped"
    assert outcomes["gyr_bias"].reason == (
        f"not applicable: no static segment with at least 10 gyroscope samples "
        f"({len(segments)} shorter ones)"
    )


def test_the_protocol_orientations_determine_the_cube_fit():
    rng = np.random.default_rng(2)
    up = np.asarray(CUBE_UP_B, dtype=float)
    # every position twice, the second a few degrees off: 24 poses, 12 orientations
    means = G * np.vstack([up, up + rng.normal(0, 0.03, up.shape)])
    coverage = orientations.cube_coverage(means)
    assert coverage.identifiable and coverage.reason == ""
    assert len(coverage.directions) == 12 and coverage.rank == 9
    assert coverage.condition < 5  # 2.4 for the ideal protocol
    assert all(sorted(s) == ["+", "-"] for s in coverage.sides.values())
    faces = orientations.cube_coverage(G * up[:6])
    assert not faces.identifiable and faces.rank == 6  # no cross terms from six faces alone


def test_directions_on_one_side_of_every_axis_are_ill_conditioned():
    rng = np.random.default_rng(1)
    means = G * np.abs(rng.normal(size=(9, 3)))  # nine distinct directions, one octant
    coverage = orientations.cube_coverage(means, tol_deg=1.0)
    assert len(coverage.directions) == 9 and coverage.rank == 9
    assert coverage.condition > orientations.MAX_CONDITION and not coverage.identifiable
    assert "one-sided axes: x (only +), y (only +), z (only +)" in coverage.reason


def test_distinct_orientations_group_by_angle_seeded_by_the_longest_pose():
    means = np.array([[0, 0, -9.8], [0.5, 0, -9.8], [-9.8, 0, 0], [0, 0, -9.8], [0, 7, 7]])
    directions, members = orientations.distinct_orientations(means, [10, 1000, 20, 30, 5])
    assert members == ((0, 1, 3), (2,), (4,))
    np.testing.assert_allclose(np.linalg.norm(directions, axis=1), 1.0)
    with pytest.raises(ValueError, match=r"a zero vector has no direction"):
        orientations.distinct_orientations(np.zeros((2, 3)))


REAL = Path(__file__).resolve().parents[3] / "shared" / "data" / "real"
CATS = Path(__file__).resolve().parents[2] / "data" / "real" / "spluque_cats_thermal"


@pytest.fixture(scope="module")
def cats():
    if not (REAL / "spluque__scikit-diveMove" / "cats_temperature_calib.nc").is_file():
        pytest.skip(f"the CATS recording is not at {REAL} (../shared is absent)")
    dataset = read_dataset(CATS)
    table, _ = ingest_recording(dataset.recordings["poses"], "poses", dataset, "test")
    return dataset, table


def test_cats_poses_found_automatically_refuse_the_cube_fit_and_keep_the_long_rests(cats):
    """The recording declared without its periods: dozens of handling pauses beside the three
    day-long poses; no matrix from three one-sided orientations, no stop on a short pause."""
    dataset, table = cats
    segments = segment_dataset({"poses": table}, fallback=True)
    assert len(segments) > 30
    outcomes = {o.name: o for o in partial.run_stages(partial_session({"poses": table}, segments))}
    assert outcomes["acc_cube"].status == "skipped"
    assert "one-sided axes: x (only -), y (only -)" in outcomes["acc_cube"].reason
    bias = outcomes["gyr_bias"].artifact
    assert bias["short_left_out"] > 10  # pauses of 1-9 s at 1 Hz
    # the long rests hold nearly every sample: the bias is theirs
    long = segments[segments["end_s"] - segments["start_s"] > 3600]
    assert bias["n_samples"] > 0.99 * (long["end_index"] - long["start_index"]).sum()


def test_cats_declared_poses_give_the_gyro_bias_only(cats):
    dataset, table = cats
    segments = segment_dataset({"poses": table}, manual=dataset.segments)
    outcomes = {o.name: o for o in partial.run_stages(partial_session({"poses": table}, segments))}
    run = sorted(name for name, o in outcomes.items() if o.status == "run")
    assert run == ["gyr_bias"]
    assert "3 distinct orientation(s) (-z, -x, -y;" in outcomes["acc_cube"].reason
    assert outcomes["gyr_bias"].artifact["n_segments"] == 3


def test_the_full_protocol_gyro_bias_leaves_a_short_pause_out():
    """The stage-per-rule gyr_bias on rotation3d pauses, one of them 4 samples long."""
    from imucal.pipeline.stages import estimate_gyr_bias

    rng = np.random.default_rng(8)
    n = 400
    t = np.arange(n) / 100.0
    gyr = GYR_BIAS + GYR_NOISE * rng.standard_normal((n, 3))
    table = pd.DataFrame({TIME: t, **dict(zip(GYR, gyr.T))})
    rows = [("a", 0, 150), ("b", 160, 164), ("c", 170, 400)]
    segments = segments_frame([segment_row("rotation3d", k, "static", t, a, b) for k, a, b in rows])
    artifact, _ = estimate_gyr_bias({"rotation3d": table}, segments, figures=False)
    assert artifact["short_left_out"] == 1 and artifact["short_left_out_samples"] == 4
    assert artifact["n_segments"] == 2 and artifact["n_samples"] == 380
