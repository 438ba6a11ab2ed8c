"""Gyroscope bias (eqs. 34-35) and scale without tools (eq. 36).

Zhang et al. (2014) calibrate the gyroscope in two ways: with a rate table (eq. 33,
:mod:`imucal.fits.ratetable`), or without tools: the bias from a static recording by the
least-squares slope of the cumulative sum (eqs. 34-35, :func:`estimate_bias`, next to the plain
mean), ``T_R,gyr`` from the rotation phases (:mod:`imucal.fits.alignment`, eqs. 28-31), then the
scale per phase from the orientation change seen by the accelerometer / magnetometer (eq. 36,
:func:`measure_angle_change` and :func:`estimate_scale`). Alignment comes before scale, as the
paper stresses.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from imucal.calibration import SensorCalibration
from imucal.columns import AXES

#: Fewest samples per static segment for a slope and a noise estimate.
MIN_STATIC_SAMPLES = 10


# --------------------------------------------------------------------------------------------
# Bias (eqs. 34-35)
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class GyroBias:
    """Gyroscope bias from static data, two estimators.

    Attributes
    ----------
    bias_ls_rad_s : ndarray, shape (3,)
        Least-squares slope of the cumulative sum (eqs. 34-35), rad/s.
    std_ls_rad_s : ndarray, shape (3,)
        Its standard deviation under white noise (exact for the sample count), rad/s.
    bias_mean_rad_s : ndarray, shape (3,)
        Plain mean of all samples, rad/s.
    std_mean_rad_s : ndarray, shape (3,)
        ``noise_std / sqrt(n)``, rad/s.
    noise_std_rad_s : ndarray, shape (3,)
        Sample noise per axis from first differences (``std(diff) / sqrt(2)``), rad/s.
    n_samples : int
        Samples used, over all segments.
    n_segments : int
    chi2_blocks : ndarray, shape (3,)
        Per axis, the chi-square of the means of consecutive blocks of :data:`BIAS_BLOCK_SAMPLES`
        samples about the overall mean, against the white noise: about ``dof_blocks`` when the
        bias holds still, larger when it wanders (bias instability, warm-up).
    dof_blocks : int
        Number of blocks minus one (0 with a single block).
    wander_var_rad2_s2 : ndarray, shape (3,)
        Per axis, the variance of the block means beyond what the white noise gives them (0 when
        they scatter no more than that): how far the bias wanders over the recording, (rad/s)^2.
    """

    bias_ls_rad_s: np.ndarray
    std_ls_rad_s: np.ndarray
    bias_mean_rad_s: np.ndarray
    std_mean_rad_s: np.ndarray
    noise_std_rad_s: np.ndarray
    n_samples: int
    n_segments: int
    chi2_blocks: np.ndarray
    dof_blocks: int
    wander_var_rad2_s2: np.ndarray


def _static_segments(static: np.ndarray | Sequence[np.ndarray]) -> list[np.ndarray]:
    if isinstance(static, np.ndarray) and static.ndim == 2:
        segments = [static]
    else:
        segments = [np.asarray(s, dtype=float) for s in static]
    if not segments:
        raise ValueError("no static data given; expected an (n, 3) array or a list of them")
    out = []
    for i, s in enumerate(segments):
        s = np.asarray(s, dtype=float)
        if s.ndim != 2 or s.shape[1] != 3:
            raise ValueError(f"static segment {i}: expected shape (n, 3), got {s.shape}")
        if len(s) < MIN_STATIC_SAMPLES:
            raise ValueError(
                f"static segment {i}: {len(s)} samples, need at least {MIN_STATIC_SAMPLES}"
            )
        bad = int(np.sum(~np.isfinite(s).all(axis=1)))
        if bad:
            raise ValueError(
                f"static segment {i}: {bad} of {len(s)} gyroscope samples are not finite; "
                "expected finite rad/s on every row"
            )
        out.append(s)
    return out


def usable_static_segments(
    pieces: Sequence[np.ndarray],
) -> tuple[list[np.ndarray], np.ndarray, dict]:
    """The static segments long enough for the bias; the shorter ones left out and counted.

    A pause of a few samples (a handled logger at 1 Hz, a robot's stop) gives neither a slope
    nor a noise estimate; it is left out rather than stopping the stage (its samples would add
    almost nothing beside the long rests).

    Parameters
    ----------
    pieces : sequence of ndarray, each shape (n_i, 3)
        Gyroscope readings (rad/s) of each static segment.

    Returns
    -------
    kept : list of ndarray
        The segments with at least :data:`MIN_STATIC_SAMPLES` samples, in order.
    keep : ndarray of bool, shape (n_segments,)
        Which segments were kept.
    left_out : dict
        ``short_left_out`` (segments), ``short_left_out_samples`` (their samples) and
        ``min_static_samples``, for the stage's record (the stages add it to their artifact
        when a segment was left out).
    """
    keep = np.array([len(p) >= MIN_STATIC_SAMPLES for p in pieces], dtype=bool)
    kept = [p for p, k in zip(pieces, keep) if k]
    left_out = {
        "short_left_out": int(np.sum(~keep)),
        "short_left_out_samples": int(sum(len(p) for p, k in zip(pieces, keep) if not k)),
        "min_static_samples": MIN_STATIC_SAMPLES,
    }
    return kept, keep, left_out


#: Samples per block of the bias's goodness of fit (10 s at 100 Hz).
BIAS_BLOCK_SAMPLES = 1000


def estimate_bias(static: np.ndarray | Sequence[np.ndarray]) -> GyroBias:
    """Gyroscope bias from static data by the cumulative-sum slope (eqs. 34-35) and the mean.

    Parameters
    ----------
    static : ndarray, shape (n, 3), or sequence of ndarray, each shape (n_i, 3)
        Gyroscope readings at rest (rad/s): the static recording, or the static pauses of
        other recordings when there is none.

    Returns
    -------
    GyroBias

    Raises
    ------
    ValueError
        If there is no data, a segment has fewer than 10 samples or non-finite values.

    Notes
    -----
    Eq. 34 sums the readings, ``y_i = sum_{k<=i} w_k``, and eq. 35 takes the least-squares slope
    of ``y_i`` against ``i``. With several segments the slope is common and each segment has its
    own intercept (each cumulative sum restarts at its segment).

    The slope is linear in the readings: ``b = sum_k C_k w_k`` with
    ``C_k = sum_{i>=k} (i - mean(i)) / S_xx``. For one segment of ``n`` samples
    ``C_k = 6 (n-k+1)(k-1) / (n (n^2-1))``, parabolic weights that vanish at both ends, sum to 1
    (so the slope is unbiased), and give ``var = sigma^2 sum C_k^2``, which tends to
    ``1.2 sigma^2 / n``: the slope's std is ``sqrt(1.2) = 1.095`` times the plain mean's
    ``sigma / sqrt(n)``. Under white noise the mean is the minimum-variance unbiased estimator;
    the paper's "does not suffer from outliers" does not hold for a linear estimator, but the
    slope does down-weight the ends of the recording, where handling disturbs the sensor.
    Both standard deviations assume white noise; bias instability adds to them on long records.
    """
    segments = _static_segments(static)
    sxy = np.zeros(3)
    sxx = 0.0
    for s in segments:
        x = np.arange(1, len(s) + 1, dtype=float)
        y = np.cumsum(s, axis=0)  # eq. 34
        xc = x - x.mean()
        sxy += xc @ (y - y.mean(axis=0))
        sxx += xc @ xc
    slope = sxy / sxx  # eq. 35, common slope over the segments
    weight_ss = 0.0
    for s in segments:
        x = np.arange(1, len(s) + 1, dtype=float)
        c = (x - x.mean()) / sxx
        weight_ss += float(np.sum(np.cumsum(c[::-1])[::-1] ** 2))
    stacked = np.vstack(segments)
    # first differences remove a slowly varying bias from the noise estimate
    diff_ss = sum(np.sum(np.diff(s, axis=0) ** 2, axis=0) for s in segments)
    diff_n = sum(len(s) - 1 for s in segments)
    noise = np.sqrt(diff_ss / diff_n / 2.0)
    n = len(stacked)
    blocks = [
        b for seg in segments for b in np.array_split(seg, max(1, len(seg) // BIAS_BLOCK_SAMPLES))
    ]
    block_means = np.array([b.mean(axis=0) for b in blocks])
    counts = np.array([len(b) for b in blocks], dtype=float)
    chi2 = np.sum(counts[:, None] * (block_means - stacked.mean(axis=0)) ** 2, axis=0) / noise**2
    white = noise**2 * np.mean(1.0 / counts)
    wander = np.zeros(3)
    if len(blocks) > 1:
        wander = np.clip(np.var(block_means, axis=0, ddof=1) - white, 0.0, None)
    return GyroBias(
        bias_ls_rad_s=slope,
        std_ls_rad_s=noise * np.sqrt(weight_ss),
        bias_mean_rad_s=stacked.mean(axis=0),
        std_mean_rad_s=noise / np.sqrt(n),
        noise_std_rad_s=noise,
        n_samples=n,
        n_segments=len(segments),
        chi2_blocks=chi2,
        dof_blocks=len(blocks) - 1,
        wander_var_rad2_s2=wander,
    )


# --------------------------------------------------------------------------------------------
# Scale without tools (eq. 36)
# --------------------------------------------------------------------------------------------


def _axis_index(axis: str) -> int:
    if axis not in AXES:
        raise ValueError(f"axis must be one of {AXES}, got {axis!r}")
    return AXES.index(axis)


def _plane_angle(vectors: np.ndarray, k: int) -> np.ndarray:
    """Angle of the projection on the plane normal to axis ``k`` (right-handed about it)."""
    i, j = (k + 1) % 3, (k + 2) % 3
    return np.arctan2(vectors[:, j], vectors[:, i])


def measure_angle_change(
    before: np.ndarray,
    during: np.ndarray,
    after: np.ndarray,
    axis: str,
    *,
    min_projection: float = 0.3,
) -> float:
    """Rotation angle of the body about ``axis`` of B from a reference vector (for eq. 36).

    A vector fixed in the world (gravity, the magnetic field) seen in the body frame turns by
    ``-phi`` about the axis when the body turns by ``+phi``. The angle of its projection on the
    plane normal to the axis (atan2) is followed through the phase and unwrapped, so full turns
    count; a raw Euler angle could not represent them (see NOTES.md).

    Parameters
    ----------
    before, after : ndarray, shape (n_b, 3) and (n_a, 3)
        Calibrated vectors (frame B) during the static pauses before and after the phase; rows
        with NaN (a 10 Hz magnetometer on a faster clock) are ignored.
    during : ndarray, shape (n, 3)
        Calibrated vectors during the phase (NaN rows ignored), only used to count turns: two
        consecutive valid samples must be less than half a turn apart.
    axis : {'x', 'y', 'z'}
        Rotation axis of the phase in frame B.
    min_projection : float
        Smallest accepted ``|projection| / |vector|`` of the pause means; below it the vector is
        too close to the axis to measure an angle (gravity in phase z).

    Returns
    -------
    float
        Signed rotation of the body about ``axis``, rad (right-handed).

    Raises
    ------
    ValueError
        If a pause has no valid sample, or the vector lies too close to the axis.

    Notes
    -----
    The end points are the angles of the pause *means*: at rest there is no dynamic
    acceleration, the 10 Hz magnetometer is not tied to a phase boundary, and averaging
    reduces the noise (about ``sigma / (|projection| sqrt(n))`` rad); the samples during the
    motion only decide the number of whole turns. The rate must then be integrated to the
    change of the pauses' mean angle (:func:`pause_mean_weights`, :func:`estimate_scale`).
    For phases x and y both gravity and the field can serve (their mean, weighted by the
    pauses' noise, has nearly the variance of the accelerometer's angle); for phase z only
    the field can.
    """
    k = _axis_index(axis)
    ends = []
    for name, block in (("before", before), ("after", after)):
        b = np.asarray(block, dtype=float)
        valid = b[np.isfinite(b).all(axis=1)]
        if len(valid) == 0:
            raise ValueError(f"the pause {name} the phase {axis!r} has no valid vector sample")
        mean = valid.mean(axis=0)
        fraction = np.hypot(mean[(k + 1) % 3], mean[(k + 2) % 3]) / np.linalg.norm(mean)
        if fraction < min_projection:
            raise ValueError(
                f"phase {axis!r}: the vector's projection on the plane normal to {axis} is "
                f"{fraction:.3f} of its norm in the pause {name}, need >= {min_projection}; "
                "a vector along the rotation axis cannot measure the angle "
                "(use the magnetometer for phase z)"
            )
        ends.append(mean)
    d = np.asarray(during, dtype=float)
    track = np.vstack([ends[0], d[np.isfinite(d).all(axis=1)], ends[1]])
    angle = np.unwrap(_plane_angle(track, k))
    return float(-(angle[-1] - angle[0]))


def pause_mean_weights(t_s: np.ndarray, before: np.ndarray, after: np.ndarray) -> np.ndarray:
    """Weights ``w`` (n,) of a rate such that ``w @ rate`` is the change of the mean angle.

    The angle at row i is the rate's trapezoidal integral up to ``t_s[i]``; ``w @ rate`` is its
    mean over the rows ``after`` minus its mean over the rows ``before``. A sensor that measures
    the angle from the mean of a pause (:func:`measure_angle_change`) sees the pause's mean
    orientation, not the orientation at one of its ends: where the pause holds the slow end of
    a turn (a segment begins where the rate falls below a threshold), an integral from the
    pause's first to the other pause's last row takes in rotation that the means do not. The
    weights rise from 0 to 1 through the pause before, in steps of the rows' share, and fall
    back to 0 through the pause after; with one row each they are the plain trapezoid rule.

    Parameters
    ----------
    t_s : ndarray, shape (n,)
        Strictly increasing sample times of the rate, s.
    before, after : ndarray of int
        Rows of ``t_s`` (indices, repeats allowed) at which the pauses' samples were taken,
        the rows of ``before`` not after those of ``after``.

    Returns
    -------
    ndarray, shape (n,)
        Weights in s.

    Raises
    ------
    ValueError
        If a set of rows is empty or out of range.
    """
    t = np.asarray(t_s, dtype=float)
    n = len(t)
    fractions = []
    for name, rows in (("before", before), ("after", after)):
        r = np.sort(np.asarray(rows, dtype=int))
        if r.size == 0 or r[0] < 0 or r[-1] >= n:
            raise ValueError(
                f"the rows of the pause {name} must be 1 or more indices in [0, {n}), got "
                f"{r.size} in [{r.min() if r.size else '-'}, {r.max() if r.size else '-'}]"
            )
        # share of the pause's rows at or after the end of interval j (rows j + 1 onwards):
        # the share of its mean angle that contains that interval's rotation
        fractions.append(1.0 - np.searchsorted(r, np.arange(1, n), side="left") / r.size)
    share = fractions[1] - fractions[0]  # interval j, (n - 1,)
    half = np.diff(t) / 2 * share
    weights = np.zeros(n)
    weights[:-1] += half
    weights[1:] += half
    return weights


@dataclass(frozen=True)
class PhaseScale:
    """Gyroscope scale of one axis from a rotation phase (eq. 36).

    Attributes
    ----------
    axis : str
    scale : float
        ``|angle_change / integrated_angle|``.
    angle_change_rad : float
        Body rotation measured from acc / mag, rad.
    integrated_angle_rad : float
        Integral of the aligned rate component over the window, rad.
    std : float or None
        Standard deviation of ``scale`` from the gyro white noise (and ``angle_std_rad``), or
        None when no noise level was given.
    max_gap_s : float
        Largest time step in the window (lost packets), s.
    sign_agrees : bool
        Whether angle change and integrated rate have the same sign (False hints at a sign or
        axis mix-up upstream).
    """

    axis: str
    scale: float
    angle_change_rad: float
    integrated_angle_rad: float
    std: float | None
    max_gap_s: float
    sign_agrees: bool


def estimate_scale(
    t_s: np.ndarray,
    rate_rad_s: np.ndarray,
    axis: str,
    angle_change_rad: float,
    *,
    noise_std_rad_s: float | None = None,
    angle_std_rad: float = 0.0,
    weights: np.ndarray | None = None,
) -> PhaseScale:
    """Scale of the gyroscope about ``axis`` from one rotation phase (eq. 36).

    Parameters
    ----------
    t_s : ndarray, shape (n,)
        Timestamps, s, strictly increasing (gaps from lost packets allowed).
    rate_rad_s : ndarray, shape (n, 3)
        Gyroscope rate after bias removal and alignment, ``T_R diag(s / s_axis) (w - o)``: the
        other axes' scales ``s`` relative to this one's (unit scale while they are not known),
        rad/s; the window runs from the pause before the phase to the pause after it.
    axis : {'x', 'y', 'z'}
        Rotation axis of the phase in frame B.
    angle_change_rad : float
        Body rotation over the same window from :func:`measure_angle_change`, rad.
    noise_std_rad_s : float, optional
        Gyro white-noise std of one sample on this axis (e.g. ``GyroBias.noise_std_rad_s``).
    angle_std_rad : float
        Standard deviation of ``angle_change_rad``.
    weights : ndarray, shape (n,), optional
        Integration weights, s, such that ``weights @ rate`` is the rotation that
        ``angle_change_rad`` measures: :func:`pause_mean_weights` for an angle between the
        means of two pauses (averaged as the angles of several sensors are). None: the
        trapezoid rule from the window's first row to its last (an angle between them).

    Returns
    -------
    PhaseScale

    Raises
    ------
    ValueError
        If the timestamps are not strictly increasing, values are not finite, or the rotation
        is too small to measure a scale (integrated angle below 0.1 rad).

    Notes
    -----
    The rate is integrated with the trapezoidal rule on the actual timestamps, not
    ``N * t_s`` as printed: with lost packets a constant step would undercount the angle. Across
    a gap the rate is interpolated linearly. The integral of white noise has variance
    ``sigma^2 sum_k w_k^2`` with the weights ``w_k`` (about ``sigma^2 T dt`` for the trapezoid
    over a window of ``T``).
    The phase axis' rate takes in the other axes' readings through the off-diagonal entries of
    ``T_R``; at unit scale their sensitivity is taken as this axis', an error of the order of
    the misalignment angle squared times the scales' spread (1e-4 for 2 deg and 10 %), which
    the relative scales remove (:func:`imucal.pipeline.stages.estimate_gyr_scale` measures
    twice). ``T_N`` is not observable without a rate table.
    """
    k = _axis_index(axis)
    t = np.asarray(t_s, dtype=float)
    w = np.asarray(rate_rad_s, dtype=float)
    if t.ndim != 1 or w.shape != (len(t), 3):
        raise ValueError(f"expected t_s (n,) and rate_rad_s (n, 3), got {t.shape} and {w.shape}")
    if len(t) < 2 or not np.all(np.isfinite(t)) or not np.all(np.isfinite(w[:, k])):
        raise ValueError(f"phase {axis!r}: timestamps and rates must be finite, at least 2 rows")
    dt = np.diff(t)
    if np.any(dt <= 0):
        i = int(np.argmax(dt <= 0))
        raise ValueError(
            f"phase {axis!r}: timestamps not strictly increasing at row {i + 1} "
            f"({t[i]!r} s -> {t[i + 1]!r} s)"
        )
    if weights is None:
        weights = pause_mean_weights(t, [0], [len(t) - 1])
    elif np.shape(weights) != t.shape:
        raise ValueError(f"weights must have the shape of t_s {t.shape}, got {np.shape(weights)}")
    integrated = float(weights @ w[:, k])
    if abs(integrated) < 0.1:
        raise ValueError(
            f"phase {axis!r}: the integrated rate is {integrated:.3g} rad; expected a rotation "
            "of at least 0.1 rad about the phase axis"
        )
    scale = abs(angle_change_rad / integrated)  # eq. 36
    std = None
    if noise_std_rad_s is not None:
        int_var = noise_std_rad_s**2 * float(weights @ weights)
        std = scale * float(
            np.sqrt(int_var / integrated**2 + angle_std_rad**2 / angle_change_rad**2)
        )
    return PhaseScale(
        axis=axis,
        scale=scale,
        angle_change_rad=float(angle_change_rad),
        integrated_angle_rad=integrated,
        std=std,
        max_gap_s=float(dt.max()),
        sign_agrees=bool(np.sign(integrated) == np.sign(angle_change_rad)),
    )


def make_calibration(
    bias: np.ndarray,
    matrix: np.ndarray,
    method: str,
    *,
    std_bias: np.ndarray | None = None,
    std_matrix: np.ndarray | None = None,
) -> SensorCalibration:
    """Gyroscope calibration from a bias and a matrix (``T_R,gyr S'_gyr`` or ``T_R diag(scale)``).

    Parameters
    ----------
    bias : ndarray, shape (3,)
        rad/s.
    matrix : ndarray, shape (3, 3)
    method : str
        Description of the variants used, for the report.
    std_bias : ndarray, shape (3,), optional
    std_matrix : ndarray, shape (3, 3), optional

    Returns
    -------
    SensorCalibration
    """
    std = {}
    if std_bias is not None:
        std["bias"] = np.asarray(std_bias, dtype=float)
    if std_matrix is not None:
        std["matrix"] = np.asarray(std_matrix, dtype=float)
    return SensorCalibration("gyr", bias, matrix, "rad/s", std, method)
