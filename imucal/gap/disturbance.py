"""Disturbances of hand-held and robot recordings, seen against an orientation reference.

Three effects of the simulator (:mod:`imucal.sim.effects.disturbance`) that a recording with an
orientation reference shows and the twin of :mod:`imucal.gap.motion` does not replay: its twin
takes the calibrated gyroscope as the true rate and renders the magnetometer from the Earth's
field alone. Each has a statistic of the gap map and an estimator of the simulator's parameters:

* ``world_magnetic``: its statistics and estimator are in :mod:`imucal.gap.worldfield`.
* ``shock``: a knock is a short, broadband spike in the accelerometer (:func:`acc_spikes`: far
  above the session's own noise and above what the motion around it does) at a time where the
  gyroscope's angle over three reference intervals departs from the reference's (the
  reference's noise telescopes, so the window's noise is one interval's). The residual alone
  is not enough: against an optical reference it has heavy tails at fast motion, with no
  knock. Statistic ``shock_rate``: such knocks per second.
* ``vibration``: the frequency of the gyroscope's strongest narrow line above the motion's
  band (:data:`LINE_MIN_HZ`), and the amplitude at that frequency of the gyroscope's residual
  against the reference, integrated into an angle at the reference's samples (so that a line
  above the reference's Nyquist frequency is measured too). Statistic ``line_power``.

The functions read recordings as :class:`imucal.gap.motionstats.MotionRecording` holds them (module
times, calibrated gyroscope, magnetometer and accelerometer, reference times and quaternions,
alignment, up).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from scipy.ndimage import maximum_filter, median_filter
from scipy.signal import welch

from imucal.gap.effects import Estimate
from imucal.gap.worldfield import (
    field_position_rms,
    position_fit,
    recording_halves,
    world_field,
    world_positions,
)
from imucal.orientation import interval_means
from imucal.sim.effects import Shock, Vibration
from imucal.validation.orientation import reference_rates

#: Reference intervals summed in a shock window (the reference's noise telescopes over them).
SHOCK_WINDOW = 3
#: Robust z (norm over the three axes) above which a window holds a knock.
SHOCK_Z = 6.0
#: Windows over which the spread a knock is scored against is taken (about 2 s).
SHOCK_SPREAD = 241
#: Running median (s) an accelerometer spike is measured from: longer than a knock (a few ms),
#: shorter than the changes of a hand's or a robot's acceleration.
SHOCK_ACC_SMOOTH_S = 0.03
#: Half-width (s) of the neighbourhood a spike is compared with, and of the part about the spike
#: left out of it; spikes closer than :data:`SHOCK_ACC_SEPARATION_S` are one.
SHOCK_ACC_NEIGHBOURHOOD_S = 1.0
SHOCK_ACC_EXCLUDE_S = 0.05
SHOCK_ACC_SEPARATION_S = 0.1
#: A knock's spike is this many times the 90th percentile of its neighbourhood's (the motion's
#: own jerks: at most 37 on the undisturbed BROAD trials, 50-490 for the taps of trials 24/25)
#: and the session's noise.
SHOCK_ACC_RATIO = 50.0
#: Lowest frequency of a vibration line (Hz): above the band of hand and robot motion and of
#: a hand's tremor (the fast hand rotations of BROAD trial 07 have their strongest "line" at
#: 5.3 Hz).
LINE_MIN_HZ = 15.0
#: Welch segments of the search for a line (s): bins of about 0.5 Hz, so that a line whose
#: frequency wanders (a phone's vibration motor: 44 Hz on BROAD trial 27) stays in one.
LINE_SEARCH_S = 2.0
#: Length of the blocks over which a line keeps its phase (s).
LINE_BLOCK_S = 5.0
#: Offsets (Hz) from a line at which the noise's share of its fitted power is measured.
LINE_OFFSETS_HZ = tuple(sign * 0.6 * k for k in range(1, 7) for sign in (-1, 1))


def reference_intervals(rec) -> tuple:
    """The calibrated gyroscope and the reference over the reference's intervals.

    Returns
    -------
    start, end : ndarray, shape (k,)
        Interval ends on the module clock, s.
    contiguous : ndarray of bool, shape (k,)
        The interval starts where the previous one ended (no gap of the reference between).
    residual : ndarray, shape (k, 3)
        Gyroscope mean minus the reference's rate carried into B, rad/s.
    """
    start, end, body = reference_rates(rec.t_reference, rec.quat)
    contiguous = np.concatenate([[False], start[1:] == end[:-1]])
    to_module = rec.alignment.to_module_time
    a, b = to_module(start), to_module(end)
    gyro = interval_means(rec.t_s, rec.gyr, a, b)
    residual = gyro - body @ rec.alignment.mounting.matrix.T
    ok = np.all(np.isfinite(residual), axis=1)
    contiguous = contiguous & np.concatenate([[False], ok[:-1]])
    return a[ok], b[ok], contiguous[ok], residual[ok]


# --------------------------------------------------------------------------- shock


def acc_noise_floor(acc: np.ndarray) -> float:
    """The accelerometer's noise (norm over the axes, m/s^2): the robust (MAD) spread of its
    first differences over sqrt 2, never below its quantisation step (readings rounded to a
    step coarser than their noise have a spread of 0)."""
    d = np.diff(acc, axis=0)
    white = 1.4826 * np.median(np.abs(d - np.median(d, axis=0)), axis=0) / np.sqrt(2.0)
    steps = np.abs(d[np.abs(d) > 1e-12 * max(float(np.max(np.abs(acc))), 1e-30)])
    step = float(np.percentile(steps, 5)) if steps.size else 0.0
    return max(float(np.linalg.norm(white)), step, 1e-12)


def acc_spikes(rec) -> tuple[np.ndarray, np.ndarray]:
    """Short spikes of the accelerometer: what a knock leaves and the motion does not.

    The readings less their running median over :data:`SHOCK_ACC_SMOOTH_S` (the smooth
    motion, gravity and linear acceleration alike) keep a spike of a few samples whole. A local
    maximum of its norm (one per :data:`SHOCK_ACC_SEPARATION_S`) is a spike when it exceeds
    :data:`SHOCK_ACC_RATIO` times both the 90th percentile of the norm over the
    :data:`SHOCK_ACC_NEIGHBOURHOOD_S` either side (the spike's own
    :data:`SHOCK_ACC_EXCLUDE_S` left out: fast motion raises its own threshold) and the
    session's noise (:func:`acc_noise_floor`).

    Returns
    -------
    times : ndarray, shape (e,)
        The spikes' peaks on the module clock, s.
    impulses : ndarray, shape (e, 3)
        Their integrals over the running median's span, m/s.
    """
    empty = np.zeros(0), np.zeros((0, 3))
    if rec.acc is None or len(rec.t_s) < 16:
        return empty
    t, acc = rec.t_s, rec.acc
    fs = (len(t) - 1) / (t[-1] - t[0])
    half = max(1, int(round(SHOCK_ACC_SMOOTH_S * fs / 2)))
    high = acc - median_filter(acc, size=(2 * half + 1, 1), mode="nearest")
    norm = np.linalg.norm(high, axis=1)
    floor = acc_noise_floor(acc)
    separation = max(1, int(round(SHOCK_ACC_SEPARATION_S * fs)))
    peak = norm == maximum_filter(norm, size=2 * separation + 1, mode="nearest")
    around, left_out = (
        int(round(SHOCK_ACC_NEIGHBOURHOOD_S * fs)),
        int(round(SHOCK_ACC_EXCLUDE_S * fs)),
    )
    times, impulses = [], []
    for i in np.flatnonzero(peak & (norm > SHOCK_ACC_RATIO * floor)):
        lo, hi = max(i - around, 0), min(i + around + 1, len(norm))
        near = np.concatenate(
            [norm[lo : max(i - left_out, lo)], norm[min(i + left_out + 1, hi) : hi]]
        )
        motion = np.percentile(near, 90) if near.size else 0.0
        if norm[i] > SHOCK_ACC_RATIO * max(motion, floor):
            span = slice(max(i - half, 0), i + half + 1)
            times.append(t[i])
            impulses.append(high[span].sum(axis=0) / fs)
    if not times:
        return empty
    return np.array(times), np.array(impulses)


def shock_events(rec) -> tuple[np.ndarray, np.ndarray, float]:
    """The knocks of one recording: accelerometer spikes (:func:`acc_spikes`) where the
    gyroscope departs from the reference.

    The gyroscope's angle against the reference's over windows of :data:`SHOCK_WINDOW`
    contiguous intervals, less its running median and scaled per axis by its running robust
    (MAD) spread over :data:`SHOCK_SPREAD` windows, is an outlier where its norm exceeds
    :data:`SHOCK_Z`. A spike is a knock when a window within one reference interval of it is
    one (the strongest gives the knock's residual angle). A spike in the reference's gaps is
    not counted; a recording without an accelerometer has none.

    Returns
    -------
    impulses : ndarray, shape (e, 3)
        The residual angle of each knock's strongest window, rad.
    acc_impulses : ndarray, shape (e, 3)
        The accelerometer's integral over each knock's spike, m/s.
    duration_s : float
        The time the windows cover, s.
    """
    none = np.zeros((0, 3))
    start, end, contiguous, residual = reference_intervals(rec)
    w = SHOCK_WINDOW
    if len(start) <= w:
        return none, none, 0.0
    covered = float(np.sum(end - start))
    times, acc_impulses = acc_spikes(rec)
    if not len(times):
        return none, none, covered
    angle = residual * (end - start)[:, None]
    total = np.concatenate([np.zeros((1, 3)), np.cumsum(angle, axis=0)])
    broken = np.concatenate([[0], np.cumsum(~contiguous)])
    k = np.arange(len(start) - w + 1)
    whole = broken[k + w] - broken[k + 1] == 0  # intervals k+1 .. k+w-1 follow their previous
    k = k[whole]
    window = total[k + w] - total[k]
    # the spread about each window, so that errors growing with the rate (a reference's
    # jitter) raise their own threshold; an isolated knock barely moves a median
    deviation = window - median_filter(window, size=(SHOCK_SPREAD, 1), mode="reflect")
    spread = 1.4826 * median_filter(np.abs(deviation), size=(SHOCK_SPREAD, 1), mode="reflect")
    # never below half the recording's typical spread (the reference's noise is always there)
    spread = np.maximum(spread, 0.5 * np.median(spread, axis=0) + 1e-300)
    z = np.linalg.norm(deviation / spread, axis=1)
    lo, hi = start[k], end[k + w - 1]
    slack = float(np.median(end - start))
    impulses, kept = [], []
    for j, t0 in enumerate(times):
        near = np.flatnonzero((hi >= t0 - slack) & (lo <= t0 + slack))
        if near.size and np.max(z[near]) > SHOCK_Z:
            impulses.append(deviation[near[np.argmax(z[near])]])
            kept.append(acc_impulses[j])
    return np.array(impulses).reshape(-1, 3), np.array(kept).reshape(-1, 3), covered


def shock_rate(rec) -> float:
    """Knocks per second of one recording (:func:`shock_events`)."""
    impulses, _, covered = shock_events(rec)
    return len(impulses) / covered if covered > 0 else 0.0


def estimate_shock(session: Mapping, half) -> Estimate | None:
    """Rate and peaks of the knocks: the rate from the knocks found (:func:`shock_events`); the
    gyroscope's peak from the median residual angle of a knock and the accelerometer's from the
    median integral of its spike, which a half-sine of peak ``A`` and duration ``D`` makes
    ``2 A D / pi`` (``D`` the simulator's realistic 5 ms: neither the reference's intervals nor
    the samples resolve it). Detection: the rate."""
    found = [shock_events(rec) for rec in recording_halves(session, half)]
    covered = sum(c for _, _, c in found)
    if covered <= 0:
        return None
    impulses = np.concatenate([i for i, _, _ in found])
    acc_impulses = np.concatenate([a for _, a, _ in found])
    rate = len(impulses) / covered
    realistic = Shock()
    to_peak = np.pi / (2 * realistic.duration_s)
    peak = acc_peak = 0.0
    if len(impulses):
        peak = float(np.median(np.linalg.norm(impulses, axis=1))) * to_peak
        acc_peak = float(np.median(np.linalg.norm(acc_impulses, axis=1))) * to_peak
    params = {
        "rate_per_s": max(rate, 1.0 / covered), "acc_peak_m_s2": acc_peak,
        "gyr_peak_rad_s": peak, "duration_s": realistic.duration_s,
    }  # fmt: skip
    return Estimate(params, rate)


# --------------------------------------------------------------------------- vibration


def line_frequency(session: Mapping) -> float | None:
    """Frequency (Hz) of the gyroscope's strongest narrow line above :data:`LINE_MIN_HZ`.

    Searched in the Welch spectrum of segments of :data:`LINE_SEARCH_S` (summed over axes) over
    its running median (15 bins either side, about 7 Hz), at its largest ratio over the recordings of the
    session; then refined in the spectrum of segments of a quarter of that recording: its
    largest bin within one search bin, by a parabola through the log spectrum."""
    best = None
    for rec in session.values():
        if len(rec.t_s) < 512:
            continue
        fs = (len(rec.t_s) - 1) / (rec.t_s[-1] - rec.t_s[0])
        coarse = int(2 ** np.round(np.log2(LINE_SEARCH_S * fs)))
        f, p = welch(rec.gyr, fs=fs, nperseg=min(coarse, len(rec.t_s)), axis=0)
        p = p.sum(axis=1)
        keep = (f >= LINE_MIN_HZ) & (f <= 0.95 * fs / 2)
        if np.count_nonzero(keep) < 8:
            continue
        idx = np.flatnonzero(keep)
        # a window centred on every bin (a falling spectrum's median is its middle value)
        floor = np.array([np.median(p[max(i - 15, 0) : i + 16]) for i in idx])
        ratio = p[idx] / np.maximum(floor, 1e-300)
        j = int(np.argmax(ratio))
        if best is not None and ratio[j] <= best[0]:
            continue
        # segments of a quarter of the recording (a power of two): a fine frequency grid
        nperseg = int(2 ** np.floor(np.log2(len(rec.t_s) / 4)))
        ff, pf = welch(rec.gyr, fs=fs, nperseg=nperseg, axis=0)
        pf = pf.sum(axis=1)
        near = np.flatnonzero((np.abs(ff - f[idx[j]]) <= f[1] - f[0]) & (ff >= LINE_MIN_HZ))
        i = int(near[np.argmax(pf[near])])
        freq = ff[i]
        if 0 < i < len(ff) - 1:
            y0, y1, y2 = np.log(pf[i - 1 : i + 2])
            denom = y0 - 2 * y1 + y2
            if denom < 0:
                freq += (ff[1] - ff[0]) * 0.5 * (y0 - y2) / denom
        best = (ratio[j], float(freq))
    return None if best is None else best[1]


def _line_power(angle: np.ndarray, t: np.ndarray, w: float) -> float:
    """``c^2 + s^2`` summed over the axes of the line ``(c sin w t - s cos w t) / w`` fitted
    with a quadratic in time to ``angle`` (shape (n, 3))."""
    tc = t - t.mean()
    design = np.column_stack([np.ones_like(t), tc, tc**2, np.sin(w * t) / w, -np.cos(w * t) / w])
    coef, *_ = np.linalg.lstsq(design, angle, rcond=None)
    return float(np.sum(coef[3] ** 2 + coef[4] ** 2))


def line_power(recordings, freq_hz: float) -> float:
    """Squared amplitude ((rad/s)^2, summed over axes) of a sinusoid of ``freq_hz`` in the
    gyroscope's residual against the reference, less the noise's (negative when the noise
    happens to be larger there).

    The residual is integrated over the reference's contiguous intervals into an angle at
    their ends, in which the reference's white orientation noise stays white (a rate from
    orientation differences has it differenced, its power piled up near the reference's
    Nyquist frequency). Over each contiguous stretch of at most :data:`LINE_BLOCK_S`, per axis,
    the angle is fitted by least squares with a quadratic in time (the gyroscope's noise
    integrates to a random walk) and the angle of the line, ``(c sin w t - s cos w t) / w``.
    The noise's part of ``c^2 + s^2`` is the same fit's at :data:`LINE_OFFSETS_HZ` from the
    line (whatever the noise's colour, it is smooth there). The difference, averaged over the
    stretches (weighted by the inverse square of the noise's part: a stretch's power scatters
    as its noise) and summed over the axes, is divided by the attenuation of the gyroscope's
    samples integrated as a polyline (``sinc^2(f / fs)``, fs the module's rate)."""
    lines, noises = [], []
    gain = 1.0
    for rec in recordings:
        a, b, contiguous, residual = reference_intervals(rec)
        if len(a) < 50:
            continue
        fs = (len(rec.t_s) - 1) / (rec.t_s[-1] - rec.t_s[0])
        gain = np.sinc(freq_hz / fs) ** 2
        run = np.cumsum(~contiguous)
        block = np.floor((a - a[0]) / LINE_BLOCK_S).astype(int)
        group = run * (block.max() + 1) + block
        for g in np.unique(group):
            sel = group == g
            if np.count_nonzero(sel) < 50:
                continue
            angle = np.cumsum(residual[sel] * (b - a)[sel][:, None], axis=0)
            lines.append(_line_power(angle, b[sel], 2 * np.pi * freq_hz))
            noises.append(np.mean([
                _line_power(angle, b[sel], 2 * np.pi * (freq_hz + df)) for df in LINE_OFFSETS_HZ
            ]))  # fmt: skip
    if not lines:
        return 0.0
    lines, noises = np.array(lines), np.array(noises)
    # a stretch's power scatters as its noise's: weight by the inverse squared noise
    weight = 1.0 / np.maximum(noises, 1e-300) ** 2
    return float(np.sum(weight * (lines - noises)) / np.sum(weight) / gain**2)


def line_power_of(rec) -> float:
    """:func:`line_power` of one recording at its own :func:`line_frequency`."""
    freq = line_frequency({"rec": rec})
    return 0.0 if freq is None else line_power([rec], freq)


def estimate_vibration(session: Mapping, half) -> Estimate | None:
    """Frequency and gyroscope amplitude of a line the reference does not see: the frequency
    from the gyroscope's spectrum over the whole recordings (:func:`line_frequency`; the twin
    replays it, so it does not score), the amplitude from the residual against the reference
    (:func:`line_power`). The accelerometer's amplitude is not compared with anything here
    and keeps the realistic ratio to the gyroscope's. Detection: the squared amplitude."""
    freq = line_frequency(session)
    if freq is None:
        return None
    power = line_power(recording_halves(session, half), freq)
    realistic = Vibration()
    ratio = realistic.acc_amp_m_s2 / realistic.gyr_amp_rad_s
    size = float(np.sqrt(max(power, 0.0)))
    params = {"freq_hz": freq, "acc_amp_m_s2": ratio * size, "gyr_amp_rad_s": size}
    return Estimate(params, power)


def disturbance_statistics(name: str, rec) -> dict:
    """The locations of one recording (stage ``reference``): ``shock_rate`` and ``line_power``
    of the gyroscope, ``field_position_rms`` of the magnetometer when it has one and, where
    the reference reports its position, ``field_dipole_peak`` (:func:`position_fit`'s
    ``peak``: a source near the path changes the field over a short stretch of it, which an
    RMS over the whole recording dilutes)."""
    key = ("reference", "gyr", "-", name)
    out = {(*key, "shock_rate"): shock_rate(rec), (*key, "line_power"): line_power_of(rec)}
    key = ("reference", "mag", "-", name)
    found = world_field(rec)
    if found is not None and rec.pos is not None:
        fit = position_fit([found], [world_positions(rec)])
        out[(*key, "field_position_rms")] = fit["rms"]
        out[(*key, "field_dipole_peak")] = fit["peak"]
    elif found is not None:
        out[(*key, "field_position_rms")] = field_position_rms(rec)
    return out
