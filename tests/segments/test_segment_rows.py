"""The segment table's rows and the filter's edges: indices, times and sizes exact."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy import signal

from imucal.columns import ACC, GYR, MAG, TIME
from imucal.segments.filtering import (
    design_lowpass,
    find_contiguous_blocks,
    lowpass_recording,
    padding_length,
)
from imucal.segments.table import segment_row, segments_frame, to_table_rows


def test_a_row_spans_its_first_to_its_last_sample_and_a_hold_has_no_sense():
    t = np.array([0.0, 0.5, 1.0, 1.5, 2.0, 2.5])
    row = segment_row("rec", "pose_1", "static", t, 1, 4)
    assert (row["start_s"], row["end_s"]) == (0.5, 1.5)  # end exclusive: the last is t[b - 1]
    assert (row["start_index"], row["end_index"]) == (1, 4)
    assert row["sense"] == 0 and np.isnan(row["turns"]) and row["axis"] == ""


def test_indices_into_the_kept_rows_map_to_the_whole_table_end_exclusive():
    """Rows 2-4 of the table were dropped: a segment over kept rows 1-3 (end exclusive) is the
    table's rows 1 and 5, so it ends at 6, not at 4 (the dropped rows are not the segment's)."""
    keep = np.array([0, 1, 5, 6, 7])
    t = np.arange(5.0)
    out = segments_frame([segment_row("rec", "a", "static", t, 1, 3)])
    out = to_table_rows(out, keep)
    assert out["start_index"].tolist() == [1] and out["end_index"].tolist() == [6]
    last = segments_frame([segment_row("rec", "b", "static", t, 3, 5)])
    assert to_table_rows(last, keep)["end_index"].tolist() == [8]


def test_no_sample_is_no_block_and_one_sample_is_one_block():
    assert find_contiguous_blocks(np.array([])) == []
    assert find_contiguous_blocks(np.array([3.0])) == [(0, 1)]


def test_a_first_order_filter_is_a_valid_order():
    sos = design_lowpass(1, 5.0, 100.0)
    assert sos.shape == (1, 6)
    with pytest.raises(ValueError, match="positive integer"):
        design_lowpass(0, 5.0, 100.0)


def test_the_padding_is_scipys_for_sections_with_zeros_in_numerator_only():
    """sosfiltfilt pads by 3 (2 n + 1 - z) samples, z the fewer of the numerators' and the
    denominators' trailing zeros, and refuses a block not longer than that: a block one sample
    longer than ``padding_length`` filters, one of that length does not."""
    sos = design_lowpass(3, 5.0, 100.0)  # odd order: one section is first order
    first = int(np.flatnonzero(sos[:, 5] == 0)[0])
    sos[first, 5] = 0.01  # its denominator no longer ends in a zero, its numerator does
    assert int((sos[:, 2] == 0).sum()) != int((sos[:, 5] == 0).sum())
    n = padding_length(sos)
    signal.sosfiltfilt(sos, np.zeros(n + 1))
    with pytest.raises(ValueError):
        signal.sosfiltfilt(sos, np.zeros(n))


def test_a_magnetometer_below_its_own_nyquist_frequency_is_filtered():
    """Accelerometer and gyroscope at 100 Hz, the magnetometer on every fourth row (25 Hz,
    Nyquist 12.5 Hz): a 10 Hz cutoff is below its Nyquist frequency, so its series is
    filtered, its white noise reduced to the filter's share (10 / 12.5 of the band), not kept."""
    rng = np.random.default_rng(3)
    n = 4000
    t = np.arange(n) / 100.0
    table = pd.DataFrame({TIME: t})
    for cols in (ACC, GYR):
        for c in cols:
            table[c] = rng.normal(0.0, 1.0, n)
    for c in MAG:
        table[c] = np.nan
        table.loc[::4, c] = rng.normal(0.0, 1.0, n // 4)
    out = lowpass_recording(table, order=4, cutoff_hz=10.0)
    before = table[list(MAG)].to_numpy()[::4]
    after = out[list(MAG)].to_numpy()[::4]
    assert np.all(np.isfinite(after)) and not np.allclose(after, before)
    # zero-phase Butterworth of order 4 at 0.8 of Nyquist passes about 0.8 of white noise's
    # power; the standard error of a variance of 1000 samples is 4.5 %
    ratio = after.var(axis=0) / before.var(axis=0)
    assert np.all((ratio > 0.6) & (ratio < 0.95)), ratio
