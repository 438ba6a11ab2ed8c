"""Effects on the inertial sensors' response and on what they sense of the setup.

``g_sensitivity``, ``earth_rotation``, ``scale_nonlinearity`` and ``lever_arm``: their specs,
the full protocol's estimators (resting means, the world-fixed rate, the rate table's
residuals and centripetal slopes) and the physics gate of the Earth's rate. The reference
scope's estimators live with the statistics they share (:mod:`imucal.gap.motionstats`).
"""

from __future__ import annotations

import numpy as np

from imucal import errormodel
from imucal.columns import AXES
from imucal.constants import EARTH_RATE_RAD_S
from imucal.gap import locations as loc
from imucal.gap import motionstats
from imucal.gap import session as ses
from imucal.gap.effects import EffectModel, Estimate
from imucal.gap.library.registry import register
from imucal.gap.library.spec import EffectSpec
from imucal.pipeline.full import SessionFit


def estimate_lever_arm(fit: SessionFit, half) -> Estimate | None:
    """Offset (m, frame B) of the accelerometer from the rate table's axis, minus the slopes
    of its run means on rate^2; detect: its norm. None without a table fit."""
    if fit.artifacts["gyr_table"] is None:
        return None
    r = -loc.centripetal_slopes(fit, half)
    r = np.nan_to_num(r)
    return Estimate(
        {"x_m": float(r[0]), "y_m": float(r[1]), "z_m": float(r[2])}, float(np.linalg.norm(r))
    )


def estimate_g_sensitivity(fit: SessionFit, half) -> Estimate | None:
    """The full matrix ``G`` of ``w_B = c + G a_B`` (rad/s per m/s^2, frame B: the model
    term's and the simulator's parameterisation) from the calibrated resting means of the
    session (:func:`imucal.gap.session.resting_means`), each gyro axis regressed on the
    three components of the specific force with a constant, as
    :func:`imucal.terms.gsensitivity.fit_g_sensitivity`; with a temperature channel the
    temperature is in the same regression (a per-axis drift over poses taken at different
    temperatures is not taken for a g-sensitivity). Detection: ``|G|`` (Frobenius). None when
    the resting segments do not span three directions of gravity."""
    rest = ses.resting_means(fit, half)
    w, f = rest.gyr, rest.acc
    columns = [np.ones(len(w)), *f.T]
    if np.any(np.isfinite(rest.temp)) and np.nanmax(rest.temp) > np.nanmin(rest.temp):
        columns.append(np.nan_to_num(rest.temp - np.nanmean(rest.temp)))
    design = np.column_stack(columns)
    ok = np.all(np.isfinite(w), axis=1) & np.all(np.isfinite(design), axis=1)
    design, w = design[ok], w[ok]
    if len(w) <= design.shape[1] + 1 or np.linalg.matrix_rank(design[:, :4]) < 4:
        return None
    coef, *_ = np.linalg.lstsq(design, w, rcond=None)
    g = coef[1:4].T  # rows: gyro axis, columns: specific-force axis
    return Estimate({"matrix": g.tolist()}, float(np.linalg.norm(g)))


def estimate_earth_rotation(fit: SessionFit, half) -> Estimate | None:
    """Latitude and rate of the world-fixed rate that the resting segments share
    (:func:`imucal.gap.locations.world_fixed_rate`: north from the magnetometer, up from the
    accelerometer); detection: its magnitude."""
    omega = loc.world_fixed_rate(fit, half)
    if omega is None:
        return None
    rate = float(np.linalg.norm(omega))
    lat = float(np.degrees(np.arctan2(omega[2], np.hypot(omega[0], omega[1])))) if rate > 0 else 0.0
    return Estimate({"latitude_deg": lat, "rate_rad_s": max(rate, 1e-12)}, rate)


def _null_std(null: list, get) -> float:
    vals = np.array([get(e) for e in null if e is not None], dtype=float)
    return float(np.std(vals, ddof=1)) if len(vals) > 2 else float("inf")


def earth_gate(est: Estimate, null: list, z: float) -> str:
    """The Earth's rate is known: a world-fixed rate beyond ``EARTH_RATE_RAD_S`` by more than
    ``z`` null standard deviations of the estimator is not the Earth."""
    s_r = _null_std(null, lambda e: e.params["rate_rad_s"])
    rate = est.params["rate_rad_s"]
    if rate > EARTH_RATE_RAD_S + z * s_r:
        return (f"world-fixed rate {rate:.3g} rad/s exceeds the Earth's {EARTH_RATE_RAD_S:.4g} "
                f"rad/s by > {z:g} null std ({s_r:.2g})")  # fmt: skip
    return ""


def estimate_scale_nonlinearity(fit: SessionFit, half) -> Estimate | None:
    """Quadratic and cubic coefficients of the gyroscope's response relative to its full scale
    (int16 counts of its sensitivity), from the rate table's residuals per axis against the
    true rate, averaged over the axes; detect: their hypotenuse. None without a table fit."""
    if fit.artifacts["gyr_table"] is None:
        return None
    opt = fit.extra["options"]
    fs = 32767 * float(opt.sensitivity["gyr"])
    rows, res, true = ses.table_residuals(fit, half)
    scale = errormodel.decompose(fit.calibration.sensor("gyr").matrix).scale
    k2, k3 = [], []
    for j, a in enumerate(AXES):
        sel = (rows["axis"] == a).to_numpy()
        w, y = true[sel, j], res[sel, j]
        if len(w) < 4:
            continue
        c, *_ = np.linalg.lstsq(np.column_stack([np.ones_like(w), w, w**2, w**3]), y, rcond=None)
        k2.append(c[2] * scale[j] * fs)
        k3.append(c[3] * scale[j] ** 2 * fs**2)
    if not k2:
        return None
    g2, g3 = float(np.mean(k2)), float(np.mean(k3))
    params = {
        "gyr_k2": g2,
        "gyr_k3": g3,
        "acc_k2": 0.0,
        "acc_k3": 0.0,
        "mag_k2": 0.0,
        "mag_k3": 0.0,
    }
    return Estimate(params, float(np.hypot(g2, g3)))


_NO_ROTATION = "no rotation in a static recording"
_ONE_ORIENTATION_G = "one orientation only: a g-dependent gyro bias is a constant bias"
_ONE_ORIENTATION_EARTH = "one orientation only: the Earth's rate is part of the constant bias"
_ONE_LEVEL = "one input level per axis in a static recording"
_OWN_LEVEL = (
    "each rest is replayed at its own level: the rests' means are not compared with each other"
)

G_SENSITIVITY = register(EffectSpec(
    name="g_sensitivity",
    description="gyroscope output proportional to the specific force (a full 3 x 3 matrix)",
    kind="systematic",
    scopes={
        "protocol": EffectModel("g_sensitivity", estimate_g_sensitivity,
                                (("gyr_static", "gyr", "g_slope"), ("gyr_static", "gyr", "spread"),
                                 ("gyr_static", "gyr", "vertical"),
                                 ("gyr_table", "gyr", "resid_rms")),
                                "gyro output proportional to specific force at rest"),
        "static": _ONE_ORIENTATION_G,
        "motion": EffectModel("g_sensitivity", motionstats.estimate_g_sensitivity,
                              (("reference", "gyr", "ref_g_slope"),
                               ("reference", "gyr", "resid_rms")),
                              "gyroscope output following the specific force (gravity along "
                              "each axis)"),
        "rests": f"{_OWN_LEVEL} (nothing gives the true rate or force of a hand-placed pose)",
        "field_fit": _ONE_ORIENTATION_G,
    },
))  # fmt: skip

EARTH_ROTATION = register(EffectSpec(
    name="earth_rotation",
    description="the gyroscope senses the Earth's rotation",
    kind="systematic",
    scopes={
        "protocol": EffectModel("earth_rotation", estimate_earth_rotation,
                                (("gyr_static", "gyr", "world_rate"),
                                 ("gyr_static", "gyr", "vertical"),
                                 ("gyr_static", "gyr", "spread")),
                                "Earth's rate in the resting gyro means: a rate fixed in the "
                                "world (north, up)", gate=earth_gate),
        "static": _ONE_ORIENTATION_EARTH,
        "motion": "below the resolution of an optical reference's rates",
        "rests": _OWN_LEVEL,
        "field_fit": _ONE_ORIENTATION_EARTH,
    },
))  # fmt: skip

SCALE_NONLINEARITY = register(EffectSpec(
    name="scale_nonlinearity",
    description="the sensing element's response a cubic of its input, relative to full scale",
    kind="systematic",
    scopes={
        "protocol": EffectModel("scale_nonlinearity", estimate_scale_nonlinearity,
                                (("gyr_table", "gyr", "rate2"), ("gyr_table", "gyr", "rate3"),
                                 ("gyr_table", "gyr", "resid_rms"),
                                 ("gyr_scale", "gyr", "scale_ratio")),
                                "rate-table residuals curved in the rate"),
        "static": _ONE_LEVEL,
        "motion": EffectModel("scale_nonlinearity", motionstats.estimate_scale_nonlinearity,
                              (("reference", "gyr", "rate2"), ("reference", "gyr", "rate3"),
                               ("reference", "gyr", "ref_scale"),
                               ("reference", "gyr", "resid_rms"),
                               ("reference", "gyr", "ori_median_rad")),
                              "gyroscope response curved in the rate (a scale that depends on "
                              "the rate)"),
        "rests": _ONE_LEVEL,
        "field_fit": "a nonlinear response is in the residual's direction dependence; no "
        "estimator reads it there",
    },
))  # fmt: skip

LEVER_ARM = register(EffectSpec(
    name="lever_arm",
    description="the accelerometer off the rotation centre: centripetal and tangential terms",
    kind="systematic",
    scopes={
        "protocol": EffectModel("lever_arm", estimate_lever_arm,
                                (("acc_table", "acc", "omega2"),),
                                "module off the rotation axis: acc run means grow with rate^2"),
        "static": _NO_ROTATION,
        "motion": "the gyroscope, not the accelerometer, is compared with the reference",
        "rests": _NO_ROTATION,
        "field_fit": _NO_ROTATION,
    },
))  # fmt: skip
