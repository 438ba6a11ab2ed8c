"""A long static recording as its full-rate window and block means (imucal.gap.blocks), and the
twin's block means drawn at the block rate (imucal.gap.twin.render_static_blocks)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest
from scipy.stats import f as f_dist

from imucal.calibration import ImuCalibration, SensorCalibration
from imucal.columns import AXES, SENSOR_COLUMNS, SENSORS, TIME
from imucal.gap import blocks as bl
from imucal.gap import locations, session
from imucal.gap.statistics import HALVES
from imucal.gap.twin import BlockSpec, Twin, quantised_moments, render_static_blocks
from imucal.sim import ProtocolConfig, World, simulate_session
from imucal.sim.session import SENSITIVITY
from imucal.sim.truth import REFERENCE_NOISE, Truth


def _recording(duration_s: float, rate_hz: float = 20.0, seed: int = 0) -> pd.DataFrame:
    """A static recording: acc/gyr every row, mag every 4th row, a temperature channel."""
    rng = np.random.default_rng(seed)
    n = int(duration_s * rate_hz)
    t = np.arange(n) / rate_hz + 12.5
    table = {TIME: t, "seq": np.arange(n) % 65536}
    for s, level in (("acc", 9.81), ("gyr", 0.01), ("mag", 0.5)):
        x = level + rng.normal(0, 0.01, (n, 3)) + 1e-6 * (t - t[0])[:, None]
        if s == "mag":
            x[np.arange(n) % 4 != 0] = np.nan
        table.update(zip(SENSOR_COLUMNS[s], x.T, strict=True))
    table["temp_c"] = 25 + 0.001 * (t - t[0])
    return pd.DataFrame(table)


def _block_means_whole(table: pd.DataFrame, size: int) -> pd.DataFrame:
    """The block means computed on the whole table at once (the reference of the pass)."""
    groups = table.drop(columns="seq").groupby(np.arange(len(table)) // size)
    out = groups.mean()
    for s in SENSORS:
        out[bl.COUNT_COLUMNS[s]] = groups[SENSOR_COLUMNS[s][0]].count()
    return out.reset_index(drop=True)


def test_one_pass_in_batches_equals_the_whole_table(monkeypatch):
    monkeypatch.setattr(bl, "STATIC_BLOCKS", 700)
    table = _recording(900.0)  # 18000 rows: blocks of 26 rows, the last one shorter
    size = bl.block_rows(len(table))
    assert size == 26 and len(table) % size
    # batches of uneven lengths that do not line up with the blocks
    cuts = [0, 1, 999, 5000, 5001, 12345, len(table)]
    batches = (table.iloc[a:b] for a, b in zip(cuts[:-1], cuts[1:]))
    window, blocks = bl.decimate_static(batches, len(table))
    t = table[TIME].to_numpy()
    assert len(window) == np.searchsorted(t, t[0] + bl.STATIC_WINDOW_S, side="right")
    pd.testing.assert_frame_equal(window, table.iloc[: len(window)].reset_index(drop=True))
    expected = _block_means_whole(table, size)
    got = blocks.table[expected.columns]
    np.testing.assert_allclose(got.to_numpy(), expected.to_numpy(dtype=float), rtol=1e-12)
    assert blocks.n_rows == len(table) and blocks.start_s == t[0]
    assert blocks.samples("mag") == pytest.approx(len(table) / 4 / len(blocks.table), rel=0.01)


def test_a_short_recording_is_used_whole_and_a_wrong_count_refused():
    table = _recording(bl.STATIC_WINDOW_S - 1)
    window, blocks = bl.decimate_static_table(table)
    assert blocks is None
    pd.testing.assert_frame_equal(window, table)
    with pytest.raises(ValueError, match="expected n_rows = 5"):
        bl.decimate_static([table], 5)


def test_long_statistics_of_one_row_blocks_equal_the_full_rate_ones(monkeypatch):
    """With blocks of one row the block statistics are the full-rate definition exactly."""
    monkeypatch.setattr(bl, "STATIC_BLOCKS", 10**6)
    table = _recording(900.0)
    window, blocks = bl.decimate_static_table(table)
    assert blocks.samples_per_block == 1 and len(window) < len(table)
    whole = SimpleNamespace(imu={"static": table}, extra={})
    cut = SimpleNamespace(imu={"static": window}, extra={"static_blocks": blocks})
    for half in HALVES:
        a, b = locations._noise(whole, half), locations._noise(cut, half)
        long_keys = [k for k in a if k[4] in ("adev_long_excess", "trend_per_s")]
        assert len(long_keys) == 18
        for k in long_keys:
            if k[4] == "trend_per_s":
                assert b[k] == pytest.approx(a[k], rel=1e-9), k
                continue
            # the same Allan deviation; the white-noise line is the window's
            white = {}
            for name, x in (("whole", table), ("window", window)):
                v = x[SENSOR_COLUMNS[k[1]][AXES.index(k[2])]].to_numpy()
                v = v[np.isfinite(v)][session.time_half(int(np.isfinite(v).sum()), half)]
                white[name] = np.std(np.diff(v))
            expected = a[k] + np.log(white["whole"] / white["window"])
            assert b[k] == pytest.approx(expected, abs=1e-9), k


def test_block_means_of_long_statistics_agree_with_full_rate_ones():
    """adev at a fifth of the recording and the trend from 1 s block means against the same
    statistics at full rate: the same white-noise expectation (log ratio 0 +- its spread)."""
    table = _recording(4000.0, rate_hz=20.0, seed=3)
    window, blocks = bl.decimate_static_table(table)
    assert blocks.samples_per_block == 8
    a = locations._noise(SimpleNamespace(imu={"static": table}, extra={}), None)
    b = locations._noise(
        SimpleNamespace(imu={"static": window}, extra={"static_blocks": blocks}), None
    )
    for k in a:
        if k[4] == "adev_long_excess":
            # 4 clusters' worth of Allan variance: log std about 0.35; the two share the data
            assert abs(b[k] - a[k]) < 0.2, (k, a[k], b[k])
        if k[4] == "trend_per_s":
            # LS slope of block means = LS slope of the rows up to the within-block spread
            assert b[k] == pytest.approx(a[k], abs=2e-7), k


def test_window_segments_cut_the_static_rows():
    table = _recording(900.0)
    window, _ = bl.decimate_static_table(table)
    seg = pd.DataFrame(
        {"recording": ["cube", "static"], "start_index": [0, 10], "end_index": [50, len(table)],
         "start_s": [0.0, 13.0], "end_s": [2.0, 900.0]}
    )  # fmt: skip
    out = bl.window_segments(seg, window)
    assert out["end_index"].tolist() == [50, len(window)]
    assert out["end_s"].iloc[1] == window[TIME].iloc[-1]


@pytest.mark.parametrize("std_counts", [0.1, 0.3, 0.7, 5.0])
def test_quantised_moments_match_rounding_noise(std_counts):
    rng = np.random.default_rng(1)
    step, value = 0.002, np.array([0.1234567, -0.0003, 0.0511])
    mean, var = quantised_moments(value, std_counts * step, step)
    draws = step * np.rint((value + rng.normal(0, std_counts * step, (400_000, 3))) / step)
    # Monte-Carlo precision of the mean: std / sqrt(400000), 5 sigma
    sd = np.sqrt(var) / np.sqrt(len(draws))
    assert np.all(np.abs(draws.mean(axis=0) - mean) < 5 * sd + 1e-12)
    # and of the variance: the std of the squared deviations / sqrt(400000), 5 sigma
    sq = (draws - draws.mean(axis=0)) ** 2
    assert np.all(np.abs(sq.mean(axis=0) - var) < 5 * sq.std(axis=0) / np.sqrt(len(draws)) + 1e-14)


def _twin(static_s: float, size: int) -> Twin:
    units = {"acc": "m/s^2", "gyr": "rad/s", "mag": "normalised"}
    ident = ImuCalibration(
        *(SensorCalibration(s, np.array([0.01, -0.02, 0.03]), np.eye(3), units[s]) for s in SENSORS)
    )
    truth = Truth(ident, World(), {"acc": 0.012, "gyr": 0.0015, "mag": 0.0008},
                  dict(REFERENCE_NOISE), np.zeros(3), "twin")  # fmt: skip
    config = ProtocolConfig(static_s=static_s)
    n = int(static_s * 100) + 1
    k = n // size
    counts = {s: np.full(k, float(size if s != "mag" else size // 10)) for s in SENSORS}
    spec = BlockSpec((np.arange(k) * size + (size - 1) / 2) / 100.0, counts, size, 100.0)
    return Twin(truth, config, None, ("static",), False, {}, [], spec)


def test_block_render_has_the_full_rate_render_block_means_distribution():
    """Block means drawn at the block rate against block means of the full-rate render of the
    same twin and seeds: the same mean (the hold's attitude and the quantiser's bias) and the
    same scatter between blocks, within what 600 s of noise allows."""
    size, static_s = 500, 600.0
    twin = _twin(static_s, size)
    for seed in (5, 6):
        full = simulate_session(twin.truth, seed, twin.config).frame("static")
        full = full.astype(float)
        drawn = render_static_blocks(twin, seed).table
        assert len(drawn) == len(twin.static_blocks.t_s)
        for s in SENSORS:
            x = full[list(SENSOR_COLUMNS[s])].to_numpy() * SENSITIVITY[s]
            k = len(drawn)
            rows = x[: k * size].reshape(k, size, 3)
            ref = np.nanmean(rows, axis=1)
            got = drawn[list(SENSOR_COLUMNS[s])].to_numpy()
            spread = np.std(ref, axis=0, ddof=1)
            # the mean of k block means differs by sqrt(2/k) of their spread (5 sigma)
            assert np.all(
                np.abs(got.mean(axis=0) - ref.mean(axis=0)) < 5 * spread * np.sqrt(2 / k)
            ), s
            # the spread: the ratio of two sample variances of k - 1 dof, F-test at 1e-4
            lo, hi = f_dist.ppf([5e-5, 1 - 5e-5], k - 1, k - 1)
            ratio = np.var(got, axis=0, ddof=1) / spread**2
            assert np.all((ratio > lo) & (ratio < hi)), (s, ratio, lo, hi)
