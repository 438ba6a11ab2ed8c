"""Magnetic effects: a magnetometer late against the gyroscope, and fields that are not the Earth's.

``mag_latency``, ``platform_magnetic`` and ``world_magnetic``: their specs, the full protocol's
estimators (the phases' lags and the field turning with the platform's outer axis) and the
physics gate of a latency. The reference scope's estimator of ``world_magnetic`` lives with the
statistics it shares (:mod:`imucal.gap.worldfield`).
"""

from __future__ import annotations

import numpy as np

from imucal.columns import AXES, MAG, SENSOR_COLUMNS, TIME, column_values
from imucal.gap import locations as loc
from imucal.gap import session as ses
from imucal.gap.effects import EffectModel, Estimate
from imucal.gap.library.registry import register
from imucal.gap.library.spec import EffectSpec
from imucal.gap.worldfield import estimate_world_magnetic
from imucal.pipeline.full import SessionFit, calibrated


def latency_gate(est: Estimate, null: list, z: float) -> str:
    """A latency delays the magnetometer alike in every rotation: the phases' lags
    (``evidence['lag_s']``) must agree with one delay within the null's spread of each
    (replicas, prediction interval). Their weighted scatter about the common delay is a
    chi-square on ``k - 1`` degrees of freedom, read against the F distribution of the null's
    ``n - 1`` (its spread is estimated) at the two-sided tail of ``z``. A field that moves with
    the platform (or any error of the calibrated field) bends the phases' angles in ways of
    their own: lags of either sign, which one delay does not explain."""
    from scipy import stats as sps

    lags = np.asarray(est.evidence.get("lag_s", ()), dtype=float)
    rows = [e.evidence.get("lag_s") for e in null if e is not None]
    rows = [r for r in rows if r is not None and len(r) == len(lags)]
    if len(lags) < 2 or len(rows) < 3:
        return ""
    null_lags = np.asarray(rows, dtype=float)
    n = np.sum(np.isfinite(null_lags), axis=0)
    spread = np.nanstd(null_lags, axis=0, ddof=1) * np.sqrt(1 + 1 / np.maximum(n, 1))
    ok = np.isfinite(lags) & np.isfinite(spread) & (spread > 0) & (n >= 3)
    if ok.sum() < 2:
        return ""
    w = 1 / spread[ok] ** 2
    delay = float(np.sum(w * lags[ok]) / np.sum(w))
    chi2 = float(np.sum(w * (lags[ok] - delay) ** 2))
    dof = int(ok.sum()) - 1
    p = float(sps.f.sf(chi2 / dof, dof, int(n[ok].min()) - 1))
    if p < 2 * sps.norm.sf(z):
        shown = ", ".join(f"{a} {x:+.3f}" for a, x in zip(AXES, lags, strict=False))
        return (f"the phases' lags ({shown} s) disagree with one delay: chi-square "
                f"{chi2:.3g} on {dof} dof against the null's spread (p = {p:.1g})")  # fmt: skip
    return ""


def estimate_mag_latency(fit: SessionFit, half) -> Estimate:
    """Delay of the magnetometer from the mean of the phases' lags, less the sample-and-hold's
    half period; the phases' lags are the evidence of :func:`latency_gate`."""
    lags = [loc.magnetometer_lag(fit, p) for p in ses.phase_half(AXES, half)]
    lag = float(np.nanmean(lags))
    mag = column_values(fit.imu["rotation3d"], MAG)
    fresh = mag[np.all(np.isfinite(mag), axis=1)]
    repeats = float(np.mean(np.all(np.diff(fresh, axis=0) == 0, axis=1))) if len(fresh) > 1 else 0.0
    packet_mag_hz = 10.0
    rate = packet_mag_hz * (1 - repeats) if repeats > 0.05 else 75.0
    delay = max(lag - 1 / (2 * rate), 0.0)
    return Estimate(
        {"rate_hz": float(rate), "delay_s": float(delay)}, lag, {"lag_s": [float(x) for x in lags]}
    )


def estimate_platform_magnetic(fit: SessionFit, half) -> Estimate | None:
    """Platform-fixed field from the resting poses' world field against the outer-axis angle
    (:func:`imucal.gap.locations.platform_field`) and the motor-current term from the
    field residual against the angular acceleration during the motion."""
    pf = loc.platform_field(fit, half)
    if pf is None:
        return None
    d_h, m_earth = pf
    rot, psi = loc.platform_motion(fit)
    t = fit.imu["rotation3d"][TIME].to_numpy(dtype=float)
    mag = calibrated(fit, "rotation3d", "mag")
    low = column_values(fit.lowpass, SENSOR_COLUMNS["gyr"])
    cal = fit.calibration.sensor("gyr")
    w_dot = np.gradient(cal.apply(low, unit=cal.unit), t, axis=0)
    d = np.array([d_h[0], d_h[1], 0.0])
    c, sn = np.cos(psi), np.sin(psi)
    d_world = np.column_stack([c * d[0] - sn * d[1], sn * d[0] + c * d[1], np.zeros_like(c)])
    pred = rot.apply(m_earth + d_world, inverse=True)
    ok = np.all(np.isfinite(mag), axis=1) & np.all(np.isfinite(w_dot), axis=1)
    r, wd = (mag - pred)[ok], w_dot[ok]
    current = float(np.sum(r * wd) / np.sum(wd * wd)) if np.sum(wd * wd) > 0 else 0.0
    params = {"field_x": float(d[0]), "field_y": float(d[1]), "field_z": 0.0,
              "current_per_rad_s2": current}  # fmt: skip
    return Estimate(params, float(np.linalg.norm(d_h)))


_NO_LAG = "no rotation in a static recording: a magnetometer lag does not show"
_CONSTANT_FIELD = "no platform activity in a static recording: its field is constant"
_PART_OF_THE_FIELD = (
    "one position and attitude: a field fixed in the world is part of the constant field"
)

MAG_LATENCY = register(EffectSpec(
    name="mag_latency",
    description="the magnetometer sampled on its own slower clock, with a delay",
    kind="systematic",
    scopes={
        "protocol": EffectModel("mag_latency", estimate_mag_latency, (("mag", "mag", "lag_s"),),
                                "magnetometer lagging the gyroscope during rotations",
                                gate=latency_gate),
        "static": _NO_LAG,
        "motion": "the twin renders the recorded motion, not a plan it could delay",
        "rests": _NO_LAG,
        "field_fit": "no gyroscope or reference: a magnetometer late against nothing is not late",
    },
))  # fmt: skip

PLATFORM_MAGNETIC = register(EffectSpec(
    name="platform_magnetic",
    description="a stray field of the platform's motors and steel, fixed to the platform",
    kind="systematic",
    scopes={
        "protocol": EffectModel("platform_magnetic", estimate_platform_magnetic,
                                (("mag", "mag", "platform_field"), ("mag", "mag", "norm_spread"),
                                 ("mag", "mag", "resid_rms"), ("mag", "mag", "dip_spread_rad")),
                                "a field turning with the platform's outer axis: |m| and the "
                                "world field change between resting poses at different "
                                "platform angles"),
        "static": _CONSTANT_FIELD,
        "motion": "no turntable in the recordings",
        "rests": _CONSTANT_FIELD,
        "field_fit": _CONSTANT_FIELD,
    },
))  # fmt: skip

WORLD_MAGNETIC = register(EffectSpec(
    name="world_magnetic",
    description="a field fixed in the world that changes with where the sensor is",
    kind="systematic",
    scopes={
        "protocol": "the platform turns the module about a point of its own: a field fixed in "
        "the world near it adds to the lab's field, which the ellipsoid and the alignment take "
        "as it is (platform_magnetic is the field that moves with the platform)",
        "static": _PART_OF_THE_FIELD,
        "motion": EffectModel("world_magnetic", estimate_world_magnetic,
                              (("reference", "mag", "field_position_rms"),
                               ("reference", "mag", "field_dipole_peak"),
                               ("reference", "mag", "dir_resid_rad")),
                              "a field fixed in the world near the path: the world field follows "
                              "the sensor's position (the reference's where it reports one, else "
                              "linear in its attitude about a pivot), not its rate"),
        "rests": _PART_OF_THE_FIELD,
        "field_fit": "no position or attitude is measured independently: a field that moves "
        "with the module's position is in the residual's slow part, which a varying ambient "
        "field fills as well",
    },
))  # fmt: skip
