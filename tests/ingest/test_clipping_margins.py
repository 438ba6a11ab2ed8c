"""Where a reading counts as clipped, to the last count (LSB), at every place that decides it.

A clipped reading is one *at* the range limit: the ingest counts it and keeps it, the fits
leave it out, the segmentation finds motions that sit on it. One count inside the limit is a
reading like any other, one count beyond it cannot come from the ADC and is refused. Each
margin is tested on both sides of the limit, one LSB apart.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from imucal.columns import ACC, GYR
from imucal.fits.accelerometer import fit_cube
from imucal.ingest import CountRange, check_count_range, sensor_limits
from imucal.io import RawDataError
from imucal.pipeline.stages import at_range
from imucal.segments.detector import MIN_CLIPPED_SAMPLES, at_extreme, is_clipped

LIMITS = {"acc": (-32768, 32767), "gyr": (-100, 100)}


def _counts(rows: list[list[float]]) -> pd.DataFrame:
    return pd.DataFrame(rows, columns=[*ACC, *GYR], dtype=float)


def test_counts_at_a_limit_are_clipped_and_one_inside_is_not():
    rows = [
        [0, 0, 0, 100, 0, 0],  # gyr at the top
        [0, 0, 0, 99, -99, 0],  # one inside both ends
        [0, 0, 0, 0, -100, 0],  # gyr at the bottom
        [32767, 0, 0, 0, 0, 0],  # acc at its (asymmetric) top
        [32766, -32767, 0, 0, 0, 0],  # one inside both ends
        [0, -32768, 0, 0, 0, 0],  # acc at its bottom
        [0, 0, 0, 100, -100, 100],  # three axes at the limit: one row
    ]
    assert check_count_range(_counts(rows), "log.csv", LIMITS, 2) == {"acc": 2, "gyr": 3}


@pytest.mark.parametrize(
    "column, value", [("gyr_x", 101), ("gyr_z", -101), ("acc_y", 32768), ("acc_x", -32769)]
)
def test_a_count_one_beyond_a_limit_is_refused(column, value):
    """Only the count beyond: the rows at the limit before it are clipped readings, not the
    first problem of the file, and do not add to the count beyond."""
    at_limit = [32767, -32768, 32767, 100, -100, 100]
    table = _counts([at_limit, at_limit, [0] * 6])
    table.loc[2, column] = value
    message = f"line 4: {column} is {value} counts, beyond the declared"
    with pytest.raises(RawDataError, match=message) as err:
        check_count_range(table, "log.csv", LIMITS, 2)
    assert f"(range_counts.{column[:3]} of dataset.yaml; 1 {column[:3]} count(s)" in str(err.value)


def test_batches_count_the_clipped_rows_of_the_whole():
    checks = CountRange("log.csv", LIMITS, 2)
    checks.update({"gyr_x": np.array([100.0, 99.0]), "gyr_y": np.array([np.nan, -100.0])}, 2)
    checks.update({"gyr_x": np.array([-99.0, -100.0])}, 2)
    checks.finish()
    assert checks.clipped == {"acc": 0, "gyr": 3}


def test_the_range_in_si_is_range_counts_times_sensitivity():
    meta = [{"sensors": ["acc", "gyr"], "sensitivity": {"acc": 0.0005985, "gyr": 0.0001332}}]
    limits = sensor_limits(meta, {"acc": 32767, "gyr": 32767})
    assert limits == {"acc": 32767 * 0.0005985, "gyr": 32767 * 0.0001332}
    # a second recording with another sensitivity: no single range
    other = meta + [{"sensors": ["gyr"], "sensitivity": {"gyr": 0.0002664}}]
    assert sensor_limits(other, {"acc": 32767, "gyr": 32767}) == {"acc": 32767 * 0.0005985}


def test_readings_at_the_range_in_si_are_clipped_and_one_lsb_inside_are_not():
    lsb = 0.0001332  # rad/s per count
    limit = 32767 * lsb
    values = np.array([[limit, 0, 0], [0, -limit, 0], [limit - lsb, 0, 0], [0, 0, lsb - limit]])
    # counts times sensitivity, as the ingest computes them
    values = np.round(values / lsb) * lsb
    np.testing.assert_array_equal(at_range(values, limit), [True, True, False, False])


def test_the_cube_fit_leaves_out_readings_at_the_range_and_keeps_one_lsb_inside():
    lsb = 0.0005985
    limit = 16383 * lsb  # a +-9.8 m/s^2 range: the face readings sit on it
    rng = np.random.default_rng(0)
    faces = np.vstack([np.eye(3), -np.eye(3)])
    tilted = np.array([[1, 1, 0], [-1, 1, 0], [0, 1, 1], [0, -1, 1], [1, 0, 1], [1, 0, -1]])
    directions = np.vstack([faces, tilted / np.sqrt(2)])
    positions = []
    for d in directions:
        p = np.round((9.7 * d + 0.02 * rng.standard_normal((60, 3))) / lsb) * lsb
        positions.append(p)
    positions[0][:7, 0] = limit  # 7 readings at the range
    positions[1][:5, 1] = limit - lsb  # 5 one count inside it
    fit = fit_cube(positions, 9.7, saturation_limit_m_s2=limit)
    assert fit.warnings == ("position 'p01': 7 of 60 saturated samples excluded (the mean of "
                            "the rest is biased towards zero on the clipped axis)",)  # fmt: skip


def test_a_motion_on_the_extreme_reading_for_enough_samples_is_clipped():
    """At least ``MIN_CLIPPED_SAMPLES`` samples and 2 % of the motion's rows on the extreme
    reading (within half a quantisation step); one sample fewer, or one step below the
    extreme, is not."""
    step = 0.01
    base = np.round(np.sin(np.linspace(0, np.pi, 400)) * 2.9 / step) * step
    x = base[:, None].copy()  # one axis: a constant one would sit on its extreme
    x[100 : 100 + MIN_CLIPPED_SAMPLES, 0] = 3.0
    assert at_extreme(x[:, 0], 0, 400, 1.0, step).sum() == MIN_CLIPPED_SAMPLES
    assert is_clipped(x, 0, 400)
    assert not is_clipped(x, 0, 99 + MIN_CLIPPED_SAMPLES)  # the motion holds one fewer
    x[100, 0] = 3.0 - step  # one step below the extreme is not on it
    assert at_extreme(x[:, 0], 0, 400, 1.0, step).sum() == MIN_CLIPPED_SAMPLES - 1
    assert not is_clipped(x, 0, 400)
    # a long motion needs 2 % of its rows: 1000 rows, 20 on the extreme
    long = np.round(np.linspace(-2, 2, 1000) / step)[:, None] * step
    long[-19:, 0] = 2.5
    assert not is_clipped(long, 0, 1000)
    long[-20:, 0] = 2.5
    assert is_clipped(long, 0, 1000)
