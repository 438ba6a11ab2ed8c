"""Zero-phase low-pass per contiguous block: response, phase, gaps, short blocks, magnetometer."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from imucal.columns import ACC, GYR, MAG, SEQ, TIME
from imucal.segments.filtering import (
    design_lowpass,
    find_contiguous_blocks,
    lowpass_block,
    lowpass_recording,
    padding_length,
)

FS = 100.0
CUTOFF = 5.0
ORDER = 4


def analog_zero_phase_gain(f_hz: float) -> float:
    """Zero-phase (forward-backward) Butterworth amplitude gain |H(f)|^2 = 1 / (1 + (f/fc)^2N).

    The bilinear transform maps the analog response onto (0, fs/2) with tan() warping, which only
    steepens it: below the cutoff the digital gain is closer to 1, above it smaller than this.
    """
    return 1.0 / (1.0 + (f_hz / CUTOFF) ** (2 * ORDER))


def sine_amplitude_phase(t: np.ndarray, x: np.ndarray, f_hz: float) -> tuple[float, float]:
    """Least-squares amplitude and phase of a sine of known frequency in ``x``."""
    design = np.column_stack([np.sin(2 * np.pi * f_hz * t), np.cos(2 * np.pi * f_hz * t)])
    (a, b), *_ = np.linalg.lstsq(design, x, rcond=None)
    return float(np.hypot(a, b)), float(np.arctan2(b, a))


def filtered_sine(f_hz: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = np.arange(0, 20.0, 1 / FS)
    x = np.sin(2 * np.pi * f_hz * t + 0.3)
    y = lowpass_block(x[:, None], design_lowpass(ORDER, CUTOFF, FS))[:, 0]
    mid = slice(len(t) // 4, 3 * len(t) // 4)  # away from the edge transients
    return t[mid], x[mid], y[mid]


def test_passband_gain_is_one():
    t, x, y = filtered_sine(0.1 * CUTOFF)
    gain = sine_amplitude_phase(t, y, 0.1 * CUTOFF)[0] / sine_amplitude_phase(t, x, 0.1 * CUTOFF)[0]
    # analog bound 1 - 1e-8; 1e-6 leaves room for the finite-length least-squares fit only
    assert abs(gain - 1) < 1e-6
    assert abs(gain - 1) <= 1 - analog_zero_phase_gain(0.1 * CUTOFF) + 1e-6


def test_stopband_attenuation():
    f = 5 * CUTOFF
    t, _, y = filtered_sine(f)
    gain = sine_amplitude_phase(t, y, f)[0]
    # order 4 forward and backward: (1 + 5^8)^-1 = 2.6e-6, i.e. -112 dB (far below -40 dB)
    bound = analog_zero_phase_gain(f)
    assert 20 * np.log10(bound) < -110
    assert gain < bound


def test_zero_phase_sine_peak_does_not_move():
    f = 1.0
    t, x, y = filtered_sine(f)
    _, phase_in = sine_amplitude_phase(t, x, f)
    _, phase_out = sine_amplitude_phase(t, y, f)
    # a one-way order-4 Butterworth would delay 1 Hz by ~0.08 s (0.5 rad); zero-phase: none
    assert abs(phase_out - phase_in) / (2 * np.pi * f) < 1e-6
    # the peak sample of a pulse stays where it was
    pulse = np.exp(-0.5 * ((np.arange(1000) - 437) / 20.0) ** 2)
    out = lowpass_block(pulse[:, None], design_lowpass(ORDER, CUTOFF, FS))[:, 0]
    assert int(np.argmax(out)) == 437


def make_table(n: int, t: np.ndarray | None = None, seq: np.ndarray | None = None) -> pd.DataFrame:
    rng = np.random.default_rng(1)
    t = np.arange(n) / FS if t is None else t
    seq = np.arange(n) % 65536 if seq is None else seq
    data = {TIME: t, SEQ: seq.astype(np.int64)}
    for c in (*ACC, *GYR):
        data[c] = rng.normal(0, 0.1, n)
    mag = rng.normal(0, 0.01, (n, 3)) + [0.3, 0.0, 0.9]
    mag[np.arange(n) % 10 != 0] = np.nan  # 10 Hz magnetometer
    for k, c in enumerate(MAG):
        data[c] = mag[:, k]
    data["temp_c"] = np.full(n, 25.0)
    return pd.DataFrame(data)


def test_blocks_split_on_seq_jump_and_time_gap_but_not_on_wrap():
    t = np.arange(20) / FS
    seq = (np.arange(20) + 65530) % 65536  # wraps at row 6: not a gap
    seq[12:] += 3  # three packets lost before row 12
    t[12:] += 3 / FS
    t[16:] += 0.5  # time gap with a contiguous counter before row 16
    seq = seq % 65536
    assert find_contiguous_blocks(t, seq) == [(0, 12), (12, 16), (16, 20)]
    # receive-time jitter with a contiguous counter: bursts (equal stamps) and 3-period steps
    t = np.arange(20) / FS
    t[5:8] = t[5]
    t[12:] += 2 / FS
    assert find_contiguous_blocks(t, np.arange(20)) == [(0, 20)]


def test_step_across_gap_does_not_leak():
    n = 1000
    table = make_table(n)
    table[list(ACC)] = 1.0
    table.loc[500:, list(ACC)] = 100.0  # a step exactly at the gap
    table.loc[500:, SEQ] += 7  # 7 lost packets
    table.loc[500:, TIME] += 7 / FS
    out = lowpass_recording(table, order=ORDER, cutoff_hz=CUTOFF)
    acc = out[list(ACC)].to_numpy()
    # a constant block stays constant; the sample next to the gap sees nothing of the step
    np.testing.assert_allclose(acc[:500], 1.0, rtol=0, atol=1e-9)
    np.testing.assert_allclose(acc[500:], 100.0, rtol=0, atol=1e-9)
    # the same block filtered alone gives the same samples (gyro: noise, not constants)
    alone = lowpass_recording(table.iloc[:500], order=ORDER, cutoff_hz=CUTOFF)
    np.testing.assert_allclose(
        out[list(GYR)].to_numpy()[:500], alone[list(GYR)].to_numpy(), atol=1e-12
    )
    assert out.attrs["lowpass"]["blocks"] == [[0, 500], [500, 1000]]

    # without the gap the step leaks across (the test above can fail)
    table[SEQ] = np.arange(n)
    table[TIME] = np.arange(n) / FS
    leaky = lowpass_recording(table, order=ORDER, cutoff_hz=CUTOFF)[list(ACC)].to_numpy()
    assert abs(leaky[499, 0] - 1.0) > 10


def test_short_block_kept_unfiltered_and_reported():
    table = make_table(400)
    table.loc[200:, SEQ] += 2
    table.loc[210:, SEQ] += 2  # rows 200..209: a 10-sample block between two gaps
    out = lowpass_recording(table, order=ORDER, cutoff_hz=CUTOFF)
    pad = padding_length(design_lowpass(ORDER, CUTOFF, FS))
    assert pad == 15
    np.testing.assert_array_equal(
        out[list(ACC)].to_numpy()[200:210], table[list(ACC)].to_numpy()[200:210]
    )
    assert not np.allclose(out[list(ACC)].to_numpy()[:200], table[list(ACC)].to_numpy()[:200])
    skipped = out.attrs["lowpass"]["unfiltered"]
    assert [(s["series"], s["rows"]) for s in skipped] == [("acc", 10), ("gyr", 10)]


def test_magnetometer_keeps_its_rate_and_nans():
    table = make_table(2000)
    nan_before = table[list(MAG)].isna().to_numpy()
    # cutoff 5 Hz is the Nyquist frequency of the 10 Hz magnetometer: left unfiltered
    out = lowpass_recording(table, order=ORDER, cutoff_hz=CUTOFF)
    np.testing.assert_array_equal(out[list(MAG)].isna().to_numpy(), nan_before)
    np.testing.assert_array_equal(out[list(MAG)].to_numpy(), table[list(MAG)].to_numpy())
    assert out.attrs["lowpass"]["mag"]["filtered"] is False
    # at 1 Hz the magnetometer is filtered at its own 10 Hz rate; NaN rows stay NaN
    out = lowpass_recording(table, order=ORDER, cutoff_hz=1.0)
    np.testing.assert_array_equal(out[list(MAG)].isna().to_numpy(), nan_before)
    mag_in = table[list(MAG)].dropna().to_numpy()
    mag_out = out[list(MAG)].dropna().to_numpy()
    # white noise of std 0.01 through a 1 Hz low-pass at 10 Hz keeps ~sqrt(2 * 1 / 10) of it
    assert np.std(mag_out[:, 0]) < 0.6 * np.std(mag_in[:, 0])
    np.testing.assert_allclose(mag_out.mean(axis=0), mag_in.mean(axis=0), atol=3e-3)
    assert out.attrs["lowpass"]["mag"]["filtered"] is True
    assert out["temp_c"].equals(table["temp_c"])


def test_refusals_name_the_value():
    with pytest.raises(ValueError, match=r"cutoff 60.0 Hz: expected 0 < cutoff < Nyquist = 50 Hz"):
        design_lowpass(ORDER, 60.0, FS)
    table = make_table(100)
    table.loc[40, TIME] = table.loc[39, TIME] - 0.001
    with pytest.raises(ValueError, match=r"t_s decreases at row 40: 0.39 s -> 0.389 s"):
        lowpass_recording(table, order=ORDER, cutoff_hz=CUTOFF)
    table = make_table(100)
    table.loc[7, ACC[1]] = np.nan
    with pytest.raises(ValueError, match=r"acc: 1 row\(s\) with NaN/inf, first at row 7"):
        lowpass_recording(table, order=ORDER, cutoff_hz=CUTOFF)


def test_the_lowest_order_is_one_and_its_gain_at_the_cutoff_is_half_power():
    """Order 1 is a filter (the smallest the design takes), order 0 is refused; a Butterworth
    of any order passes the cutoff at half power."""
    from scipy import signal

    from imucal.segments.filtering import design_lowpass

    for order in (1, 2):
        sos = design_lowpass(order, 5.0, 100.0)
        _, h = signal.sosfreqz(sos, worN=[5.0], fs=100.0)
        assert abs(h[0]) ** 2 == pytest.approx(0.5, rel=1e-9)
    with pytest.raises(ValueError, match="filter order 0"):
        design_lowpass(0, 5.0, 100.0)
