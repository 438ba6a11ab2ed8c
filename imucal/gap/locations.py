"""The per-stage statistics of a calibrated session: the values at the gap map's locations.

Each function computes the statistics of one stage (timing, noise, accelerometer cube,
gyroscope at rest, rate table, gyroscope scale, magnetometer, reference, temperature) from the
ingested tables, the segments and the session's own fit, for the whole session or one half
(:mod:`imucal.gap.session`); :func:`imucal.gap.statistics.compute_statistics` gathers them and
:data:`imucal.gap.statistics.CATALOGUE` says how each is scored. The effect estimators
(:mod:`imucal.gap.library`) read the same quantities through the public functions here.
"""

from __future__ import annotations

from collections.abc import Mapping
from itertools import product

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation

from imucal import errormodel
from imucal.columns import (
    AXES,
    SENSOR_COLUMNS,
    SENSORS,
    SEQ,
    TIME,
    column_values,
    temperature_column,
)
from imucal.gap.blocks import long_series
from imucal.gap.clipping import pile_up_rows
from imucal.gap.session import (
    alternate_half,
    integrate_orientation,
    magnetometer_lag_fit,
    mid_times,
    phase_half,
    resting_means,
    run_half,
    segment_means,
    segment_rows,
    table_residuals,
    time_half,
)
from imucal.ingest.timebase import unwrap_seq
from imucal.pipeline.full import SessionFit, calibrated
from imucal.segments.table import row_bounds

#: Unit "up" directions a cube or V-block can hold (faces, edges, corners), shape (26, 3).
NOMINAL_DIRECTIONS = np.array([v for v in product((-1, 0, 1), repeat=3) if any(v)], dtype=float)


NOMINAL_DIRECTIONS /= np.linalg.norm(NOMINAL_DIRECTIONS, axis=1, keepdims=True)


#: Largest angle (deg) between a measured gravity direction and its nearest nominal one for a
#: pose to count as nominal (the 26 directions are >= 35 deg apart).
NOMINAL_TOLERANCE_DEG = 10.0


def lost_packets(seq: np.ndarray) -> tuple[int, int, np.ndarray]:
    """Lost packets from a 16-bit counter.

    Returns
    -------
    lost : int
    expected : int
        Packets the counter says were sent over the rows' span.
    gaps : ndarray of int
        Length of every gap (packets), shape (k,).
    """
    step = np.diff(unwrap_seq(np.asarray(seq)))
    gaps = step[step > 1] - 1
    return int(gaps.sum()), int(step.sum()) + 1, gaps


def stamp_residual(t_s: np.ndarray, seq: np.ndarray) -> np.ndarray:
    """Receive timestamps about the straight line of the packet clock (s), shape (n,)."""
    k = unwrap_seq(np.asarray(seq)).astype(float)
    a = np.polyfit(k - k.mean(), t_s, 1)
    return t_s - np.polyval(a, k - k.mean())


def stamp_resolution(t_s: np.ndarray) -> float:
    """The resolution of recorded timestamps (s): the coarsest power of ten, 1 s to 1 ns,
    that every stamp is a multiple of (as a file written with that many decimals holds them),
    0 when none is (stamps of full float precision).

    Parameters
    ----------
    t_s : ndarray, shape (n,)
    """
    t = np.asarray(t_s, dtype=float)
    t = t[np.isfinite(t)]
    for d in range(10):
        scaled = t * 10.0**d
        if np.all(np.abs(scaled - np.rint(scaled)) <= 1e-3):
            return 10.0**-d
    return 0.0


def stamp_floor(fit: SessionFit) -> float:
    """The smallest stamp scatter the session's timestamps can show (s): the rounding of its
    stamps' resolution (:func:`stamp_resolution` of every IMU recording, or the twin's
    ``stamp_resolution_s``, which a replica carries from its session), ``resolution /
    sqrt(12)``, and at least 1e-7 s. A replica held in memory is not rounded as the session's
    file was; below this floor the two cannot differ by more than that rounding."""
    res = fit.extra.get("stamp_resolution_s")
    if res is None:
        res = max(stamp_resolution(t[TIME].to_numpy(dtype=float)) for t in fit.imu.values())
    return max(float(res) / np.sqrt(12.0), 1e-7)


def allan_deviation(x: np.ndarray, m: int) -> np.ndarray:
    """Overlapping Allan deviation at cluster size ``m`` samples, per column.

    Parameters
    ----------
    x : ndarray, shape (n, k)
        Rate samples (equally spaced).
    m : int

    Returns
    -------
    ndarray, shape (k,)
    """
    c = np.vstack([np.zeros((1, x.shape[1])), np.cumsum(x, axis=0)])
    n = len(x)
    if n < 2 * m + 1:
        return np.full(x.shape[1], np.nan)
    d = c[2 * m :] - 2 * c[m : n + 1 - m] + c[: n + 1 - 2 * m]
    return np.sqrt(np.mean(d**2, axis=0) / (2 * m * m))


def _timing(fit: SessionFit, half) -> dict:
    lost = expected = 0
    scatter = []
    for table in fit.imu.values():
        sl = time_half(len(table), half)
        seq = table[SEQ].to_numpy()[sl]
        t = table[TIME].to_numpy(dtype=float)[sl]
        n_lost, n_exp, _ = lost_packets(seq)
        lost, expected = lost + n_lost, expected + n_exp
        res = stamp_residual(t, seq)
        scatter.append(res - np.median(res))
    out = {("ingest", "clock", "-", "all", "loss_fraction"): lost / max(expected, 1)}
    r = np.concatenate(scatter)
    out[("ingest", "clock", "-", "all", "stamp_scatter_s")] = float(
        max(np.sqrt(np.mean(r**2)), stamp_floor(fit))
    )
    return out | clipping_locations(fit, half)


def clip_fractions(tables: Mapping[str, pd.DataFrame], options, half=None) -> dict[str, float]:
    """Per sensor, the fraction of its samples (all recordings, one time half or all) that
    clip: within 1.5 LSB of its declared range (``options.limit``: ``range_counts`` of
    dataset.yaml) or at a pile-up of identical extreme values in its recording
    (:func:`imucal.gap.clipping.pile_up_rows`: a part whose range is smaller than declared, or
    not declared at all)."""
    out = {}
    for s in SENSORS:
        n = hit = 0
        for table in tables.values():
            x = column_values(table, SENSOR_COLUMNS[s])
            ok = np.all(np.isfinite(x), axis=1)
            clipped = pile_up_rows(x)
            if options.limit(s) is not None:
                limit = options.limit(s) - 1.5 * float(options.sensitivity[s])
                clipped |= np.any(np.abs(np.nan_to_num(x)) >= limit, axis=1) & ok
            sl = time_half(len(table), half)
            hit += int(clipped[sl][ok[sl]].sum())
            n += int(ok[sl].sum())
        if n:
            out[s] = hit / n
    return out


def clipping_locations(fit: SessionFit, half) -> dict:
    """Fraction of samples that clip, per sensor (:func:`clip_fractions`)."""
    fractions = clip_fractions(fit.imu, fit.extra["options"], half)
    return {("ingest", s, "-", "all", "clip_fraction"): f for s, f in fractions.items()}


def _noise(fit: SessionFit, half) -> dict:
    """White noise and the 10 s Allan deviation from the static recording's full-rate rows (its
    window when it is long); the trend and the Allan deviation at a fifth of the recording from
    its block means (:func:`imucal.gap.blocks.long_series`: the rows themselves when short)."""
    table = fit.imu["static"]
    t = table[TIME].to_numpy(dtype=float)
    sl = time_half(len(t), half)
    fs = 1 / np.median(np.diff(t))
    series, samples, _ = long_series(fit.imu, fit.extra.get("static_blocks"))
    t_long = series[TIME].to_numpy(dtype=float)
    sl_long = time_half(len(t_long), half)
    out = {}
    for s in SENSORS:
        x = column_values(table, SENSOR_COLUMNS[s])[sl]
        tt = t[sl]
        good = np.all(np.isfinite(x), axis=1)
        x, tt = x[good], tt[good]
        rate = fs if s != "mag" else 1 / np.median(np.diff(tt))
        white = np.std(np.diff(x, axis=0), axis=0) / np.sqrt(2)
        m10 = max(int(round(10 * rate)), 1)
        xl = column_values(series, SENSOR_COLUMNS[s])[sl_long]
        tl = t_long[sl_long]
        good = np.all(np.isfinite(xl), axis=1)
        xl, tl = xl[good], tl[good]
        slope = np.polyfit(tl - tl.mean(), xl, 1)[0]
        mlong = max(int(len(xl) / 5), 1)
        # the white-noise line at the cluster's number of samples (rows x samples per row)
        white_long = white / np.sqrt(mlong * samples[s])
        for j, a in enumerate(AXES):
            ad10 = allan_deviation(x[:, [j]], m10)[0]
            adl = allan_deviation(xl[:, [j]], mlong)[0]
            out[("noise", s, a, "static", "adev_10s_excess")] = float(
                np.log(ad10 / (white[j] / np.sqrt(m10)))
            )
            out[("noise", s, a, "static", "adev_long_excess")] = float(np.log(adl / white_long[j]))
            out[("noise", s, a, "static", "trend_per_s")] = float(slope[j])
    return out


def _cube(fit: SessionFit, half) -> dict:
    rows = alternate_half(segment_rows(fit, "cube", "position"), half)
    acc = segment_means(calibrated(fit, "cube", "acc"), rows)
    g = fit.extra["options"].gravity_m_s2
    r = np.linalg.norm(acc, axis=1) - g
    tm = mid_times(fit, "cube", rows)
    out = {
        ("acc_cube", "acc", "norm", "position", "resid_rms"): float(np.sqrt(np.mean(r**2))),
        ("acc_cube", "acc", "norm", "position", "resid_time_slope"): float(
            np.polyfit(tm - tm.mean(), r, 1)[0]
        ),
    }
    res = cube_direction_residuals(fit, half)[0]
    # a hold by hand is not at the nominal orientation: its direction says nothing of the fit
    if len(res) >= 3 and "cube" not in fit.extra["options"].held_by_hand:
        out[("acc_cube", "acc", "dir", "position", "dir_resid_rad")] = float(
            np.sqrt(np.mean(np.sum(res**2, axis=1)))
        )
    return out


def nearest_nominal(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Nearest nominal cube direction of each unit vector.

    Parameters
    ----------
    u : ndarray, shape (p, 3)
        Unit gravity ("up") directions in B.

    Returns
    -------
    nominal : ndarray, shape (p, 3)
    angle_rad : ndarray, shape (p,)
    """
    cos = u @ NOMINAL_DIRECTIONS.T
    k = np.argmax(cos, axis=1)
    return NOMINAL_DIRECTIONS[k], np.arccos(np.clip(cos[np.arange(len(u)), k], -1, 1))


def cube_direction_residuals(fit: SessionFit, half) -> tuple[np.ndarray, np.ndarray, Rotation]:
    """Tilt of each cube position's calibrated gravity direction from its nominal direction.

    The calibrated accelerometer means of the positions, as unit vectors, are matched to the
    nearest of :data:`NOMINAL_DIRECTIONS` (poses further than ``NOMINAL_TOLERANCE_DEG`` are
    dropped), one common rotation (the cube's mounting in B, Wahba / Kabsch) is fitted, and
    the residual of each position is the small rotation vector ``n_rot x u`` (rad,
    perpendicular to gravity). A placement error tilts each pose on its own, which a norm
    (eq. 32) fit cannot see but these residuals can.

    Returns
    -------
    residual_rad : ndarray, shape (p, 3)
    noise_var_rad2 : ndarray, shape (p,)
        Variance of one component of each residual from the white noise of the position mean.
    mounting : Rotation
        The common rotation (nominal -> measured).
    """
    _, u, nominal, noise = _nominal_cube_positions(fit, half)
    if len(u) < 3:
        return np.zeros((0, 3)), np.zeros(0), Rotation.identity()
    rot, _ = Rotation.align_vectors(u, nominal)
    return np.cross(rot.apply(nominal), u), noise, rot


def _nominal_cube_positions(fit: SessionFit, half):
    """The cube positions whose calibrated gravity direction is within
    ``NOMINAL_TOLERANCE_DEG`` of a nominal one: their rows, unit directions ``u`` and nominal
    directions (each (p, 3)) and the white-noise variance of one component of ``u`` (p,)."""
    rows = alternate_half(segment_rows(fit, "cube", "position"), half)
    acc = calibrated(fit, "cube", "acc")
    means = segment_means(acc, rows)
    var = []
    for a, b in row_bounds(rows):
        x = acc[a:b]
        var.append(np.mean(np.var(np.diff(x, axis=0), axis=0) / 2) / max(len(x), 1))
    norm = np.linalg.norm(means, axis=1)
    ok = np.isfinite(norm) & (norm > 0)
    u = means[ok] / norm[ok, None]
    nominal, angle = nearest_nominal(u)
    keep = angle < np.radians(NOMINAL_TOLERANCE_DEG)
    noise = (np.asarray(var)[ok][keep] / norm[ok][keep] ** 2) if len(var) else np.zeros(0)
    return rows[ok][keep], u[keep], nominal[keep], noise


def cube_joint_tilts(fit: SessionFit, half) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Tilt of each cube position about the axis that the accelerometer and the magnetometer
    both see: a rigid turn of the cube moves both, an error of one sensor moves only its own.

    A placement error turns the cube, so gravity and the Earth field turn together in B and
    the angle between them stays the field's (90 deg + dip); an accelerometer bias or
    temperature drift turns only the gravity direction, a magnetometer error only the field.
    With ``u0 = R n`` a position's mounted nominal direction (``R`` the common rotation of
    :func:`cube_direction_residuals`, fitted on the accelerometer), ``m`` its field direction
    and ``e = (u0 x m) / |u0 x m|``, a rotation ``t`` of the cube gives

    * the accelerometer's tilt about ``e``: ``a = (u0 x u) . e = t . e`` (plus its own error),
    * the field's: ``f = angle(u0, m) - psi = t . e`` (plus the magnetometer's error).

    A common rotation ``w`` (the part of the placements that ``R`` absorbed, and between the
    magnetometer's and the accelerometer's frames the calibration's alignment error) adds
    ``w . e``, and ``psi`` is the field's angle: both series are taken as residuals of the
    same least-squares fit on ``[1, e]`` over all positions (4 parameters, so that a half's
    6 positions keep most of their freedom). ``sum(a f)`` then has expectation
    ``sigma^2 sum(1 - h_ii)`` for rotations of std ``sigma`` about every axis, and none from
    either sensor's own error or noise (independent of the other's).

    Parameters
    ----------
    fit : SessionFit
    half : {None, 'A', 'B'}
        The residuals of all positions or of alternate ones.

    Returns
    -------
    acc_tilt_rad : ndarray, shape (p,)
        ``a`` of each nominal position with a field, after the fit (rad).
    field_tilt_rad : ndarray, shape (p,)
        ``f`` of the same positions, after the fit (rad).
    free : ndarray, shape (p,)
        ``1 - h_ii`` (``h`` the fit's hat matrix). Empty arrays when fewer than five nominal
        positions have a field.
    """
    rows, u, nominal, _ = _nominal_cube_positions(fit, None)
    mag = segment_means(calibrated(fit, "cube", "mag"), rows)
    norm = np.linalg.norm(mag, axis=1)
    ok = np.isfinite(norm) & (norm > 0)
    design = np.zeros((int(ok.sum()), 4))
    if len(design) <= design.shape[1]:
        return np.zeros(0), np.zeros(0), np.zeros(0)
    mount, _ = Rotation.align_vectors(u, nominal)
    u, u0, m = u[ok], mount.apply(nominal[ok]), mag[ok] / norm[ok, None]
    e = np.cross(u0, m)
    e /= np.linalg.norm(e, axis=1, keepdims=True)
    design = np.column_stack([np.ones(len(e)), e])
    # I - H of the fit on [1, e]
    resid = np.eye(len(e)) - design @ np.linalg.pinv(design.T @ design) @ design.T
    acc = resid @ np.sum(np.cross(u0, u) * e, axis=1)
    field = resid @ np.arccos(np.clip(np.sum(u0 * m, axis=1), -1.0, 1.0))
    mine = rows.index[ok].isin(alternate_half(segment_rows(fit, "cube", "position"), half).index)
    return acc[mine], field[mine], np.diag(resid)[mine]


def table_mount_tilts(fit: SessionFit) -> np.ndarray:
    """Tilt (rad vector, perpendicular to gravity) of each rate-table mounting from nominal.

    The table spins about the vertical, so the calibrated gravity direction at a mounting's
    rest run is its spin axis in B; its angle from the nearest nominal direction is that
    mounting's placement tilt. Returns shape (k, 3), one row per mounting with a rest run.
    """
    if "ratetable" not in fit.imu:
        return np.zeros((0, 3))
    rows = segment_rows(fit, "ratetable", "run")
    rows = rows[rows["rate_dps"] == 0]
    if rows.empty:
        return np.zeros((0, 3))
    means = segment_means(calibrated(fit, "ratetable", "acc"), rows)
    u = means / np.linalg.norm(means, axis=1, keepdims=True)
    nominal, angle = nearest_nominal(u)
    keep = angle < np.radians(NOMINAL_TOLERANCE_DEG)
    return np.cross(nominal[keep], u[keep])


def resting_gyro(fit: SessionFit, half) -> tuple[np.ndarray, np.ndarray]:
    """Calibrated gyro and accelerometer means at the cube positions, each shape (p, 3)."""
    rows = alternate_half(segment_rows(fit, "cube", "position"), half)
    return segment_means(calibrated(fit, "cube", "gyr"), rows), segment_means(
        calibrated(fit, "cube", "acc"), rows
    )


def _gyr_rest(fit: SessionFit, half) -> dict:
    if "cube" in fit.extra["options"].held_by_hand:  # the hand sways: the gyro is not at rest
        return {}
    w, f = resting_gyro(fit, half)
    out = {}
    up = f / np.linalg.norm(f, axis=1, keepdims=True)
    for j, a in enumerate(AXES):
        out[("gyr_static", "gyr", a, "position", "spread")] = float(np.sqrt(np.mean(w[:, j] ** 2)))
        out[("gyr_static", "gyr", a, "position", "g_slope")] = float(
            np.polyfit(f[:, j], w[:, j], 1)[0]
        )
    design = np.column_stack([np.ones(len(w)), up[:, 0], up[:, 1], up[:, 2]])
    # isotropic vertical component: w_p = c + v * up_p (c a constant offset, per axis)
    a_mat = np.vstack(
        [np.column_stack([np.eye(3)[j][None].repeat(len(w), 0), up[:, j]]) for j in range(3)]
    )
    coef, *_ = np.linalg.lstsq(a_mat, w.T.ravel(), rcond=None)
    del design
    out[("gyr_static", "gyr", "up", "position", "vertical")] = float(coef[3])
    return out


#: Components of a world-fixed rate: magnetic north, east, up.
WORLD_AXES = ("north", "east", "up")


def world_fixed_rate(fit: SessionFit, half) -> np.ndarray | None:
    """A rate fixed in the world (the Earth's) seen at the resting segments, in world axes.

    At each resting segment (:func:`resting_means`) the calibrated gyro mean is
    ``c + [n e u] Omega``: ``n, e, u`` the world's magnetic north, east and up in the body
    frame (from the magnetometer and the accelerometer), ``c`` a constant (the bias the
    calibration left), ``Omega`` the world-fixed rate; least squares weighted by the white
    noise of each mean.

    Returns
    -------
    ndarray, shape (3,) or None
        ``Omega`` (rad/s: north, east, up); None with fewer than 4 segments that have all three
        sensors.
    """
    rest = resting_means(fit, half)
    ok = np.all(np.isfinite(rest.north), axis=1)
    if ok.sum() < 4:
        return None
    weight = 1 / np.sqrt(rest.gyr_var[ok])  # (r, 3)
    blocks = [
        np.column_stack([np.eye(3), n, e, u]) * w[:, None]
        for n, e, u, w in zip(rest.north[ok], rest.east[ok], rest.up[ok], weight, strict=True)
    ]
    coef, *_ = np.linalg.lstsq(np.vstack(blocks), (rest.gyr[ok] * weight).ravel(), rcond=None)
    return coef[3:]


def _world_rate(fit: SessionFit, half) -> dict:
    omega = world_fixed_rate(fit, half)
    if omega is None:
        return {}
    return {("gyr_static", "gyr", a, "rest", "world_rate"): float(v)
            for a, v in zip(WORLD_AXES, omega, strict=True)}  # fmt: skip


def _table(fit: SessionFit, half) -> dict:
    rows, res, true = table_residuals(fit, half)
    out = {}
    for j, a in enumerate(AXES):
        out[("gyr_table", "gyr", a, "run", "resid_rms")] = float(np.sqrt(np.mean(res[:, j] ** 2)))
        sel = (rows["axis"] == a).to_numpy()
        w = true[sel, j]
        y = res[sel, j]
        if len(w) >= 4:
            design = np.column_stack([np.ones_like(w), w, w**2, w**3])
            c, *_ = np.linalg.lstsq(design, y, rcond=None)
            out[("gyr_table", "gyr", a, "run", "rate2")] = float(c[2])
            out[("gyr_table", "gyr", a, "run", "rate3")] = float(c[3])
    all_runs = run_half(segment_rows(fit, "ratetable", "run"), half)
    out[("gyr_table", "gyr", "-", "run", "left_out")] = float(
        (~all_runs["label"].isin(fit.artifacts["gyr_table"]["labels"])).sum()
    )
    out.update(_centripetal(fit, half))
    return out


def centripetal_slopes(fit: SessionFit, half) -> np.ndarray:
    """Slope of the calibrated acc run means on rate^2, per acc axis (m), shape (3,).

    For each table axis the run means minus that axis's rest-run mean, regressed on rate^2
    over the runs whose axis is not the acc axis (the centripetal term ``-w^2 r_perp``).
    """
    rows = run_half(segment_rows(fit, "ratetable", "run"), half)
    acc = segment_means(calibrated(fit, "ratetable", "acc"), rows)
    w2 = np.radians(rows["rate_dps"].to_numpy(float)) ** 2
    slopes = np.full(3, np.nan)
    for j, a in enumerate(AXES):
        xs, ys = [], []
        for b in AXES:
            if b == a:
                continue
            sel = (rows["axis"] == b).to_numpy()
            if sel.sum() < 3:
                continue
            y = acc[sel, j]
            x = w2[sel]
            xs.append(x - x.mean())
            ys.append(y - y.mean())
        if xs:
            x, y = np.concatenate(xs), np.concatenate(ys)
            slopes[j] = float(x @ y / (x @ x))
    return slopes


def _centripetal(fit: SessionFit, half) -> dict:
    s = centripetal_slopes(fit, half)
    return {("acc_table", "acc", a, "run", "omega2"): float(s[j]) for j, a in enumerate(AXES)}


def _scale(fit: SessionFit, half) -> dict:
    if fit.artifacts["gyr_scale"] is None:
        return {}
    per_phase = fit.artifacts["gyr_scale"]["per_phase"]
    final = errormodel.decompose(fit.calibration.sensor("gyr").matrix).scale
    out = {}
    for p in phase_half(per_phase, half):
        j = AXES.index(p)
        out[("gyr_scale", "gyr", p, "phase", "scale_ratio")] = float(
            per_phase[p]["scale"] / final[j] - 1
        )
    return out


def magnetometer_lag(fit: SessionFit, phase: str) -> float:
    """Lag of the calibrated magnetometer behind the gyroscope during one phase (s);
    :func:`magnetometer_lag_fit` without its standard deviation."""
    return magnetometer_lag_fit(fit, phase)[0]


def dip_angles(fit: SessionFit, half) -> np.ndarray:
    """Dip (rad) in every static rotation3d pause and cube position with field samples."""
    out = []
    for rec, kind in (("rotation3d", "static"), ("cube", "position")):
        rows = alternate_half(segment_rows(fit, rec, kind), half)
        acc = segment_means(calibrated(fit, rec, "acc"), rows)
        mag = segment_means(calibrated(fit, rec, "mag"), rows)
        ok = np.all(np.isfinite(mag), axis=1)
        a, m = acc[ok], mag[ok]
        s = -np.sum(a * m, axis=1) / (np.linalg.norm(a, axis=1) * np.linalg.norm(m, axis=1))
        out.append(np.arcsin(np.clip(s, -1, 1)))
    return np.concatenate(out)


def platform_motion(fit: SessionFit) -> tuple[Rotation, np.ndarray]:
    """Orientation and outer-axis angle of the rotation3d recording (cached in ``fit.extra``).

    The calibrated gyro is integrated from the first resting pose, whose calibrated specific
    force defines the world vertical. The platform's outer axis is taken as the world
    vertical: its angle ``psi`` is the integral of the world-vertical component of the
    angular rate (turns about horizontal axes leave it unchanged).

    Returns
    -------
    rotation : Rotation, length n
        B -> world per sample.
    psi_rad : ndarray, shape (n,)
    """
    cache = fit.extra.setdefault("_cache", {})
    if "platform" not in cache:
        table = fit.imu["rotation3d"]
        t = table[TIME].to_numpy(dtype=float)
        gyr = calibrated(fit, "rotation3d", "gyr")
        first = segment_rows(fit, "rotation3d", "static").iloc[:1]
        up = segment_means(calibrated(fit, "rotation3d", "acc"), first)[0]
        r0, _ = Rotation.align_vectors([[0.0, 0.0, 1.0]], [up / np.linalg.norm(up)])
        rot = Rotation.from_quat(integrate_orientation(t, gyr, r0.as_quat()))
        w_up = rot.apply(np.nan_to_num(gyr))[:, 2]
        psi = np.concatenate([[0.0], np.cumsum(0.5 * (w_up[1:] + w_up[:-1]) * np.diff(t))])
        cache["platform"] = (rot, psi)
    return cache["platform"]


def resting_field(fit: SessionFit, half) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Calibrated field at the rotation3d resting poses, in B and in the world.

    Returns
    -------
    m_b : ndarray, shape (p, 3)
        Mean calibrated field per pose (B).
    m_world : ndarray, shape (p, 3)
        The same turned to the world by the integrated orientation at the pose's middle.
    psi_rad : ndarray, shape (p,)
        Platform outer-axis angle at the pose.
    """
    rows = alternate_half(segment_rows(fit, "rotation3d", "static"), half)
    m_b = segment_means(calibrated(fit, "rotation3d", "mag"), rows)
    rot, psi = platform_motion(fit)
    mid = ((rows["start_index"].to_numpy(int) + rows["end_index"].to_numpy(int)) // 2).clip(
        0, len(psi) - 1
    )
    ok = np.all(np.isfinite(m_b), axis=1)
    return m_b[ok], rot[mid[ok]].apply(m_b[ok]), psi[mid[ok]]


def platform_field(fit: SessionFit, half) -> tuple[np.ndarray, np.ndarray] | None:
    """Horizontal field turning with the platform's outer axis, from the resting poses.

    Model: ``m_world,p = m_earth + Rz(psi_p) d`` (a field fixed to the outer axis, in world
    axes at ``psi = 0``); the horizontal parts are linear in ``(m_earth_h, d_h)``. ``d_z`` is
    not separable from the Earth's vertical field.

    Returns
    -------
    (d_h, m_earth) or None
        ``d_h`` shape (2,) and ``m_earth`` shape (3,), normalised field units; None when the
        poses do not span two outer-axis angles at least 20 deg apart.
    """
    _, m_w, psi = resting_field(fit, half)
    if len(psi) < 2:
        return None
    spread = np.abs(np.angle(np.exp(1j * (psi[:, None] - psi[None, :]))))
    if spread.max() < np.radians(20.0):
        return None
    c, s = np.cos(psi), np.sin(psi)
    one, zero = np.ones_like(c), np.zeros_like(c)
    design = np.vstack([np.column_stack([one, zero, c, -s]), np.column_stack([zero, one, s, c])])
    coef, *_ = np.linalg.lstsq(design, np.concatenate([m_w[:, 0], m_w[:, 1]]), rcond=None)
    m_earth = np.array([coef[0], coef[1], float(np.mean(m_w[:, 2]))])
    return coef[2:], m_earth


def _mag(fit: SessionFit, half) -> dict:
    m = calibrated(fit, "rotation3d", "mag")
    m = m[np.all(np.isfinite(m), axis=1)]
    m = m[time_half(len(m), half)]
    norm = fit.extra["options"].field_norm
    out = {
        ("mag", "mag", "norm", "rotation3d", "resid_rms"): float(
            np.sqrt(np.mean((np.linalg.norm(m, axis=1) - norm) ** 2))
        ),
        ("mag", "mag", "dip", "static", "dip_spread_rad"): float(np.std(dip_angles(fit, half))),
    }
    for p in phase_half(AXES, half):
        out[("mag", "mag", p, "phase", "lag_s")] = magnetometer_lag(fit, p)
    m_b, _, _ = resting_field(fit, half)
    if len(m_b) >= 2:
        out[("mag", "mag", "norm", "static", "norm_spread")] = float(
            max(np.std(np.linalg.norm(m_b, axis=1)), 1e-9)
        )
    pf = platform_field(fit, half)
    if pf is not None:
        out[("mag", "mag", "h", "static", "platform_field")] = float(
            max(np.linalg.norm(pf[0]), 1e-9)
        )
    return out


def reference_clock_locations(fit: SessionFit, half) -> dict:
    """The reference clock against the module's: its offset at the start (s, relative to the
    reference's first sample) and, on the whole session, its drift (ppm)."""
    ta = fit.time_alignment
    if half is None:
        offset = ta.offset_s - fit.reference_start_s
        return {
            ("validate", "clock", "-", "rotation3d", "ref_offset_s"): float(offset),
            ("validate", "clock", "-", "rotation3d", "ref_drift_ppm"): float(ta.drift_ppm),
        }
    w = np.asarray(ta.window_offset_s)[0 if half == "A" else 1 :: 2]
    return {
        ("validate", "clock", "-", "rotation3d", "ref_offset_s"): float(
            np.mean(w) - fit.reference_start_s
        )
    }


def mean_temperature(fit: SessionFit, recording: str, rows: pd.DataFrame) -> np.ndarray | None:
    """Mean temperature (deg C) over each segment row, shape (r,); None without a channel."""
    col = temperature_column(fit.imu[recording])
    if col is None:
        return None
    return segment_means(column_values(fit.imu[recording], [col]), rows)[:, 0]


def _temperature(fit: SessionFit, half) -> dict:
    rest = resting_means(fit, half)
    ok = np.isfinite(rest.temp)
    if ok.sum() < 4 or np.ptp(rest.temp[ok]) <= 0:
        return {}
    temp, gyr = rest.temp[ok], rest.gyr[ok]
    acc = np.linalg.norm(rest.acc[ok], axis=1) - fit.extra["options"].gravity_m_s2
    x = temp - temp.mean()
    out = {
        ("temperature", "acc", "norm", "rest", "temp_slope"): float(
            x @ (acc - acc.mean()) / (x @ x)
        )
    }
    for j, a in enumerate(AXES):
        out[("temperature", "gyr", a, "rest", "temp_slope")] = float(
            x @ (gyr[:, j] - gyr[:, j].mean()) / (x @ x)
        )
    return out
