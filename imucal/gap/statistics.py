"""Location-wise statistics of a calibrated session: the coordinates of the gap map.

A location is ``(stage, sensor, axis, segment, statistic)``. Every statistic is a physical
quantity computed from the ingested tables, the segments and the session's own fit, the same
way for a recorded session and for its twin replicas, so that its null distribution comes
from the replicas. Each can also be computed on one half of the segments (``half='A'`` or
``'B'``: alternate positions, runs at alternate rates, the phases x/z against y, the first
and second half of a long recording in time) for the held-out check of the attribution.

Statistics (units in :data:`CATALOGUE`; a static recording's own in :mod:`imucal.gap.streams`):

* timing: fraction of lost packets from the counter, timestamp scatter about the packet
  clock, clipped fraction per sensor;
* noise: Allan deviation of the static recording at 10 s and at a fifth of its length, as
  log-ratio to the white-noise prediction, and its linear trend;
* accelerometer cube: RMS and time slope of the ``|a| - g`` position residuals;
* gyroscope at rest: spread of the calibrated position means, their slope on specific force,
  their component along the vertical; the world-fixed rate (north, east, up) that all resting
  segments share (the Earth's); a cube held by hand (``PipelineOptions.held_by_hand``) is not
  at rest: its positions give no gyro-at-rest statistic and no direction residual, for the
  session and its replicas alike;
* rate table: RMS of the run-mean residuals, their rate^2 and rate^3 coefficients, runs left
  out; accelerometer run means against rate^2 (centripetal);
* gyroscope scale without tools: eq. 36 scale over the final scale, per phase;
* accelerometer cube directions: RMS angle of the calibrated gravity directions from the
  nearest nominal cube/V-block direction after one common rotation (placement errors);
* magnetometer: ``|m| - 1`` RMS, spread of the dip, lag behind the gyroscope per phase,
  spread of ``|m|`` over the resting poses and the horizontal field that turns with the
  platform's vertical (outer) axis;
* reference: clock offset at the start and drift;
* temperature channel (when present): slopes of resting residuals on temperature.

This module holds the catalogue and :func:`compute_statistics`, which gathers the locations of
one session; the per-stage statistic functions are in :mod:`imucal.gap.locations`, the
session's rows, halves, resting means and clock that they share with the effect estimators
(:mod:`imucal.gap.library`) and the model terms (:mod:`imucal.terms`) in
:mod:`imucal.gap.session`, so that a statistic and the estimator that reads the same quantity
cannot drift apart.
"""

from __future__ import annotations

from dataclasses import dataclass

from imucal.gap.locations import (
    _cube,
    _gyr_rest,
    _mag,
    _noise,
    _scale,
    _table,
    _temperature,
    _timing,
    _world_rate,
    reference_clock_locations,
)
from imucal.pipeline.full import SessionFit

HALVES = (None, "A", "B")


@dataclass(frozen=True)
class StatisticInfo:
    """How a statistic is scored against its null.

    Attributes
    ----------
    unit : str
    log : bool
        Scored as ``log`` of the value (positive scale statistics, closer to Gaussian).
    floor : float
        Resolution of the statistic (same unit, after ``log`` if any): added in quadrature to
        the replica spread so that a statistic that is constant under the null (e.g. zero lost
        packets) is not scored against a zero spread.
    """

    unit: str
    log: bool = False
    floor: float = 0.0


#: Statistics of the full-protocol diagnosis: name -> scoring info.
PROTOCOL_STATISTICS = {
    "loss_fraction": StatisticInfo("1", floor=2e-5),
    "stamp_scatter_s": StatisticInfo("s", log=True, floor=0.05),
    "clip_fraction": StatisticInfo("1", floor=2e-5),
    "adev_10s_excess": StatisticInfo("log ratio", floor=0.02),
    "adev_long_excess": StatisticInfo("log ratio", floor=0.02),
    "trend_per_s": StatisticInfo("SI/s"),
    "resid_rms": StatisticInfo("SI", log=True, floor=0.02),
    "resid_time_slope": StatisticInfo("SI/s"),
    "spread": StatisticInfo("rad/s", log=True, floor=0.02),
    "g_slope": StatisticInfo("rad/s per m/s^2"),
    "vertical": StatisticInfo("rad/s"),
    "world_rate": StatisticInfo("rad/s"),
    "rate2": StatisticInfo("1/(rad/s)"),
    "rate3": StatisticInfo("1/(rad/s)^2"),
    "left_out": StatisticInfo("runs", floor=0.5),
    "omega2": StatisticInfo("m"),
    "scale_ratio": StatisticInfo("1"),
    "dip_spread_rad": StatisticInfo("rad", log=True, floor=0.02),
    "lag_s": StatisticInfo("s"),
    "ref_offset_s": StatisticInfo("s", floor=1e-4),
    "ref_drift_ppm": StatisticInfo("ppm", floor=1.0),
    "temp_slope": StatisticInfo("SI/K"),
    "dir_resid_rad": StatisticInfo("rad", log=True, floor=0.02),
    "norm_spread": StatisticInfo("1", log=True, floor=0.02),
    "platform_field": StatisticInfo("1", log=True, floor=0.02),
}


#: Statistics that only the streams of a static recording have (:mod:`imucal.gap.streams`;
#: it also measures ``stamp_scatter_s``, the noise statistics and ``temp_slope``).
STATIC_STATISTICS = {
    "stamp_wander_s": StatisticInfo("s", log=True, floor=0.05),
    "burst_fraction": StatisticInfo("1", floor=2e-3),
    "long_gap_fraction": StatisticInfo("1", floor=2e-4),
}


#: Statistics of a session's pooled short rests (:mod:`imucal.gap.rests`; it also measures
#: ``stamp_scatter_s``, ``burst_fraction`` and ``long_gap_fraction``).
REST_STATISTICS = {
    "rest_noise": StatisticInfo("SI", log=True, floor=0.02),
    "rest_still_fraction": StatisticInfo("1", floor=2e-3),
    "rest_adev_excess": StatisticInfo("log ratio", floor=0.02),
    "rest_trend_per_s": StatisticInfo("SI/s"),
}


#: Statistics of a magnetometer's field-fit residual (:mod:`imucal.gap.fieldfit`).
FIELD_FIT_STATISTICS = {
    "fit_resid_rms": StatisticInfo("1", log=True, floor=0.02),
    "fit_resid_slow": StatisticInfo("log ratio", floor=0.02),
    "fit_resid_direction": StatisticInfo("1", log=True, floor=0.02),
}


#: Statistics that only recordings with an orientation reference have (:mod:`imucal.gap.motion`;
#: it also measures ``resid_rms``, ``rate2``, ``rate3`` and ``dir_resid_rad``). The floors of
#: the slopes are what a calibration against a reference can resolve: a scale of 1e-4, a
#: g-sensitivity of 2e-5 rad/s per m/s^2 (0.01 deg/s per g, below any datasheet's).
MOTION_STATISTICS = {
    "ori_median_rad": StatisticInfo("rad", log=True, floor=0.02),
    "ref_scale": StatisticInfo("1", floor=1e-4),
    "ref_g_slope": StatisticInfo("rad/s per m/s^2", floor=2e-5),
    # the disturbances' (imucal.gap.disturbance): one knock in 200 s; a line of 3 mrad/s; a
    # field in the world uniform to 1 % of the Earth's (0.44 uT of 44): what a magnetometer
    # calibration resolves (its residual is 1-2 % on the BROAD recordings), so the twin, whose
    # field is the calibration's, cannot tell less from the calibration's own error
    "shock_rate": StatisticInfo("1/s", floor=0.005),
    "line_power": StatisticInfo("(rad/s)^2", floor=1e-5),
    "field_position_rms": StatisticInfo("1", floor=0.01),
    # the largest departure of a dipole's field near the path (imucal.gap.worldfield
    # .position_fit): a maximum over the path, so the calibration's residual RMS on BROAD
    # (1.7 %, 0.75 uT) rather than its mean; an undisturbed BROAD trial's dipole reached 0.035
    "field_dipole_peak": StatisticInfo("1", floor=0.02),
}


#: Every statistic a diagnosis scores: name -> scoring info.
CATALOGUE = {
    **PROTOCOL_STATISTICS,
    **STATIC_STATISTICS,
    **REST_STATISTICS,
    **FIELD_FIT_STATISTICS,
    **MOTION_STATISTICS,
}


Key = tuple  # (stage, sensor, axis, segment, statistic)


def compute_statistics(fit: SessionFit, half: str | None = None) -> dict[Key, float]:
    """Every statistic of a fitted session (see the module docstring).

    Parameters
    ----------
    fit : SessionFit
    half : {None, 'A', 'B'}
        All segments, or one half of them.

    Returns
    -------
    dict
        ``(stage, sensor, axis, segment, statistic)`` -> value (units in :data:`CATALOGUE`);
        a statistic the session cannot give (no rate table, no reference, no temperature
        channel) is absent, a degenerate one is NaN.
    """
    out: dict[Key, float] = {}
    out.update(_timing(fit, half))
    if "static" in fit.imu:
        out.update(_noise(fit, half))
    out.update(_cube(fit, half))
    out.update(_gyr_rest(fit, half))
    out.update(_world_rate(fit, half))
    if fit.artifacts["gyr_table"] is not None:
        out.update(_table(fit, half))
    out.update(_scale(fit, half))
    out.update(_mag(fit, half))
    if fit.time_alignment is not None:
        out.update(reference_clock_locations(fit, half))
    out.update(_temperature(fit, half))
    return out
