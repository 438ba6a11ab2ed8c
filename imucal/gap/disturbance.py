"""Disturbances of hand-held and robot recordings, seen against an orientation reference.

Three effects of the simulator (:mod:`imucal.sim.effects.disturbance`) that a recording with an
orientation reference shows and the twin of :mod:`imucal.gap.motion` does not replay: its twin
takes the calibrated gyroscope as the true rate and renders the magnetometer from the Earth's
field alone. Each has a statistic of the gap map and an estimator of the simulator's parameters:

* ``world_magnetic``: the field carried into the world by the reference's orientation is
  constant in a clean recording; a field fixed in the world near the path makes it follow the
  sensor's position. Where the reference reports the position (``pos``, m), the world field
  is fitted as a function of it (:func:`position_fit`: a uniform gradient, and a dipole with
  its centre free where it predicts held-out blocks better); statistic
  ``field_position_rms``: the RMS of that part. Without a position, a module turned about a
  pivot (wrist, flange) has its position linear in the entries of its orientation matrix, and
  the statistic is the RMS of the world field's part linear in those entries (a field that
  follows the position, not the attitude, is then not seen). A magnetometer lag makes the
  world field follow the rate (fitted beside it, :func:`_field_fit`), the reference's noise
  and jitter make it scatter; neither is a function of the position or linear in the
  attitude.
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
from scipy.optimize import least_squares
from scipy.signal import welch
from scipy.spatial.transform import Rotation

from imucal.gap.effects import Estimate
from imucal.orientation import interval_means, up_vector
from imucal.sim.effects import Shock, Vibration, WorldMagnetic
from imucal.sim.effects.disturbance import dipole_field, gradient_matrix
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
#: Fewest reference samples with a field for the world field's regression.
MIN_FIELD_SAMPLES = 200
#: Most reference samples of the world field's regression on the position (taken evenly: the
#: field near the path changes over tens of cm, a hand or robot covers that in 0.1 s or more).
MAX_POSITION_SAMPLES = 1500
#: Nearest a dipole of the position fit may sit to the path, m: a magnet is not inside the
#: module, and a centre closer than this fits single samples' noise.
DIPOLE_MIN_DISTANCE_M = 0.05
#: Farthest a dipole of the position fit may sit from the path, m: a source farther away
#: changes the field smoothly along it, as the lab's own field does, which the gradient takes.
DIPOLE_MAX_DISTANCE_M = 0.5
#: Offsets (m) from the path at which the dipole's centre is first searched.
DIPOLE_SEARCH_M = (0.1, 0.25)
#: Path samples the dipole's centre is first searched about.
DIPOLE_SEARCH_POINTS = 30
#: Contiguous blocks of the samples alternated in the held-out comparison of the dipole with
#: the gradient alone.
HELDOUT_BLOCKS = 8


def _halves(session: Mapping, half) -> list:
    return [rec.half(half) for rec in session.values()]


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


# --------------------------------------------------------------------------- world_magnetic


def twin_world_turn(rec) -> Rotation:
    """The rotation from the reference's world to the twin's: up to +z, and the magnetometer's
    mean field in the world (when the recording has one) to the x-z plane, north +x, as the
    simulator's world has it (:class:`imucal.sim.World`). With it a field added in the twin's
    world meets the Earth's field at the angles it met it in the recording."""
    tilt, _ = Rotation.align_vectors([[0.0, 0.0, 1.0]], [up_vector(rec.up)])
    found = world_field(rec)
    if found is None:
        return tilt
    north = tilt.apply(found[0].mean(axis=0))
    return Rotation.from_euler("z", -np.arctan2(north[1], north[0])) * tilt


def world_field(rec, tilt: bool = False) -> tuple | None:
    """The magnetometer and the gyroscope carried into the world at the present reference
    samples.

    Parameters
    ----------
    rec : MotionRecording
    tilt : bool
        Express them in the twin's world (:func:`twin_world_turn`) instead of the reference's.

    Returns
    -------
    field : ndarray, shape (k, 3)
        ``R M^T m_B`` (normalised field), R the reference's body -> world.
    orientation : ndarray, shape (k, 3, 3)
        ``R M^T`` (B -> world).
    rate : ndarray, shape (k, 3)
        The gyroscope's rate in the world, rad/s.
    None when the recording has no magnetometer or too few samples.
    """
    if rec.mag is None:
        return None
    tau, use, t_m, m = _field_samples(rec)
    if np.count_nonzero(use) < MIN_FIELD_SAMPLES:
        return None
    m_at = np.column_stack([np.interp(tau[use], t_m, m[:, k]) for k in range(3)])
    w_at = np.column_stack([np.interp(tau[use], rec.t_s, rec.gyr[:, k]) for k in range(3)])
    q = rec.quat[use]
    orientation = (
        Rotation.from_quat(q[:, [1, 2, 3, 0]]).as_matrix() @ rec.alignment.mounting.matrix.T
    )
    if tilt:
        orientation = twin_world_turn(rec).as_matrix() @ orientation
    field = np.einsum("nij,nj->ni", orientation, m_at)
    return field, orientation, np.einsum("nij,nj->ni", orientation, w_at)


def _field_samples(rec) -> tuple:
    """Module times of the reference's samples, which of them :func:`world_field` uses (an
    orientation, within the magnetometer's span; with a position where the recording has one),
    and the magnetometer's fresh times and readings."""
    tau = rec.alignment.to_module_time(rec.t_reference)
    fresh = np.all(np.isfinite(rec.mag), axis=1)
    t_m, m = rec.t_s[fresh], rec.mag[fresh]
    use = np.all(np.isfinite(rec.quat), axis=1) & (tau >= t_m[0]) & (tau <= t_m[-1])
    if rec.pos is not None:
        use &= np.all(np.isfinite(rec.pos), axis=1)
    return tau, use, t_m, m


def world_positions(rec, tilt: bool = False) -> np.ndarray | None:
    """The reference's positions (m, shape (k, 3)) at the samples of :func:`world_field`, in
    the reference's world or (``tilt``) the twin's; None without a position or a field."""
    if rec.pos is None or rec.mag is None:
        return None
    _, use, _, _ = _field_samples(rec)
    if np.count_nonzero(use) < MIN_FIELD_SAMPLES:
        return None
    pos = rec.pos[use]
    return twin_world_turn(rec).apply(pos) if tilt else pos


def _field_fit(parts: list) -> tuple:
    """The world field regressed on an offset per recording, the 9 entries of the orientation
    and a lag: ``m_w = m_0 + C vec(R) + tau (omega_w x m_w)`` (a magnetometer ``tau`` late
    reads ``R(t - tau)^T m`` and turns the world field by ``tau omega_w``; one ``tau`` for the
    three components, so that a lag, which follows the rate, is not taken for a field that
    follows the attitude).

    Parameters
    ----------
    parts : list of tuple
        :func:`world_field` per recording.

    Returns
    -------
    offsets : ndarray, shape (k, 3)
        ``m_0`` of each sample's recording.
    coef : ndarray, shape (9, 3)
        ``C`` (rows: the entries of R, row-major).
    lag : ndarray, shape (k, 3)
        ``tau (omega_w x m_w)``.
    field, orientation : ndarray
        The parts joined.
    """
    field = np.concatenate([p[0] for p in parts])
    orientation = np.concatenate([p[1] for p in parts])
    turn = np.cross(np.concatenate([p[2] for p in parts]), field)
    which = np.concatenate([np.full(len(p[0]), k) for k, p in enumerate(parts)])
    one_hot = (which[:, None] == np.arange(len(parts))[None, :]).astype(float)
    design = np.column_stack([one_hot, orientation.reshape(len(field), 9)])
    both = np.linalg.lstsq(design, np.hstack([field, turn]), rcond=None)[0]
    # the shared lag by least squares on what the other regressors leave (Frisch-Waugh)
    res_field, res_turn = field - design @ both[:, :3], turn - design @ both[:, 3:]
    tau = float(np.sum(res_field * res_turn) / max(np.sum(res_turn**2), 1e-300))
    coef = both[:, :3] - tau * both[:, 3:]
    return one_hot @ coef[: len(parts)], coef[len(parts) :], tau * turn, field, orientation


#: Bases of the linear field ``C`` per arm component: what a static field fixed in the world
#: gives (its gradient, symmetric and traceless: :func:`gradient_matrix`) and what is not a field
#: in the world (the identity, ``R b``: a hard iron that moves with the board, a magnet on it or
#: a bias the calibration left; the cross products, ``(R q) x m_0``: the magnetometer's axes
#: turned by ``q`` against the reference's, a calibration that leaves it misaligned to the
#: gyroscope).
GRADIENT_BASIS = tuple(gradient_matrix(*e) for e in np.eye(5))
BOARD_BASIS = (np.eye(3), *(np.cross(np.eye(3), e) for e in np.eye(3)))


def _board_regressors(parts: list) -> tuple:
    """The world field of ``parts`` (:func:`world_field`, one per recording) stacked, shape
    (3 k,), and what is no field in the world, shape (3 k, c): an offset per recording,
    :data:`BOARD_BASIS` times ``R e_j`` (a hard iron, a turned magnetometer) and a lag (the
    world field turned by ``omega_w``)."""
    field = np.concatenate([p[0] for p in parts])
    orientation = np.concatenate([p[1] for p in parts])
    rate = np.concatenate([p[2] for p in parts])
    which = np.concatenate([np.full(len(p[0]), k) for k, p in enumerate(parts)])
    offsets = np.kron((which[:, None] == np.arange(len(parts))).astype(float), np.eye(3))
    board = [
        np.einsum("ij,nj->ni", b, orientation[:, :, k]).ravel()
        for b in BOARD_BASIS
        for k in range(3)
    ]
    return field.ravel(), np.column_stack([offsets, *board, np.cross(rate, field).ravel()])


def position_fit(parts: list, positions: list) -> dict:
    """The world field as a function of the sensor's position, beyond the board's own errors.

    The world field (:func:`world_field`) less what is no field in the world
    (:func:`_board_regressors`, projected out) is fitted by a field fixed in the world: a
    uniform gradient ``G (p - p_mean)`` (symmetric, traceless: :func:`gradient_matrix`), and a
    dipole near the path (:func:`dipole_field`: centre free, at least
    :data:`DIPOLE_MIN_DISTANCE_M` from every sample, moment linear) when it predicts the field
    better held out than the gradient alone (fitted on alternate blocks of
    :data:`HELDOUT_BLOCKS`, compared on the others). At most :data:`MAX_POSITION_SAMPLES`
    samples, taken evenly.

    Parameters
    ----------
    parts : list of tuple
        :func:`world_field` per recording.
    positions : list of ndarray, shape (k_i, 3)
        :func:`world_positions` per recording, m, in the same world.

    Returns
    -------
    dict
        ``rms`` (normalised field: the RMS about its mean of the fitted field's part that
        depends on the position), ``peak`` (the largest departure along the path of the
        dipole's field from its mean, normalised field; 0 without a dipole), ``gradient``
        (3 x 3, per m), ``centre`` (m, or None without a dipole), ``moment`` (field times m^3,
        zeros without a dipole).
    """
    n_all = sum(len(p[0]) for p in parts)
    step = max(1, int(np.ceil(n_all / MAX_POSITION_SAMPLES)))
    parts = [(f[::step], o[::step], w[::step]) for f, o, w in parts]
    pos = np.concatenate([p[::step] for p in positions])
    y, board = _board_regressors(parts)
    q, _ = np.linalg.qr(board)

    def left(x: np.ndarray) -> np.ndarray:
        return x - q @ (q.T @ x)

    y = left(y)
    centred = pos - pos.mean(axis=0)
    grad = left(np.column_stack([(centred @ gradient_matrix(*e)).ravel() for e in np.eye(5)]))
    blocks = np.repeat(np.arange(len(pos)) * HELDOUT_BLOCKS // len(pos), 3)
    fit_on, held = blocks % 2 == 0, blocks % 2 == 1

    def dipole(c: np.ndarray) -> np.ndarray:
        return left(np.column_stack([dipole_field(pos, c, e).ravel() for e in np.eye(3)]))

    def resid(design: np.ndarray, rows=slice(None)) -> np.ndarray:
        coef = np.linalg.lstsq(design[rows], y[rows], rcond=None)[0]
        return y - design @ coef

    def distance(c: np.ndarray) -> float:
        return float(np.min(np.linalg.norm(pos - c, axis=1)))

    picks = pos[np.linspace(0, len(pos) - 1, DIPOLE_SEARCH_POINTS).astype(int)]
    offsets = np.vstack([np.eye(3), -np.eye(3)])
    starts = [p + d * o for p in picks for d in DIPOLE_SEARCH_M for o in offsets]
    starts = [c for c in starts if distance(c) >= DIPOLE_MIN_DISTANCE_M]
    best = None
    for c in starts:
        rss = float(np.sum(resid(np.hstack([grad, dipole(c)])) ** 2))
        if best is None or rss < best[0]:
            best = (rss, c)
    centre = None
    if best is not None:
        refined = least_squares(
            lambda c: resid(np.hstack([grad, dipole(c)])), best[1], x_scale=0.05, max_nfev=60
        ).x
        near = DIPOLE_MIN_DISTANCE_M <= distance(refined) <= DIPOLE_MAX_DISTANCE_M
        centre = refined if near else best[1]
        # the dipole stays where it predicts the held-out blocks better than the gradient alone
        with_dipole = np.hstack([grad, dipole(centre)])
        if np.sum(resid(with_dipole, fit_on)[held] ** 2) >= np.sum(resid(grad, fit_on)[held] ** 2):
            centre = None
    design = grad if centre is None else np.hstack([grad, dipole(centre)])
    coef = np.linalg.lstsq(design, y, rcond=None)[0]
    part = (design @ coef).reshape(-1, 3)
    part -= part.mean(axis=0)
    peak = 0.0
    if centre is not None:
        local = (design[:, 5:] @ coef[5:]).reshape(-1, 3)
        peak = float(np.max(np.linalg.norm(local - local.mean(axis=0), axis=1)))
    return {
        "rms": float(np.sqrt(np.mean(np.sum(part**2, axis=1)))),
        "peak": peak,
        "gradient": gradient_matrix(*coef[:5]),
        "centre": centre,
        "moment": np.zeros(3) if centre is None else coef[5:8],
    }


def field_position_rms(rec) -> float | None:
    """RMS (normalised field) of the world field's part that a static field fixed in the world
    gives: a function of the reference's position where the recording has one
    (:func:`position_fit`), else about a pivot, ``G R r``, beyond what the board's own errors
    give.

    The world field (:func:`world_field`) is regressed first on what is no field in the world
    (:data:`BOARD_BASIS` times ``R e_k``: a hard iron, a turned magnetometer), an offset and a
    lag (the world field turned by ``omega_w``); then what is left on the gradients
    (:data:`GRADIENT_BASIS` times ``R e_k``, 15 regressors). The second fit's part is the
    statistic: what a calibration's own errors explain is not credited to a field in the world,
    also where the motion does not tell the two apart (a short or slow recording).
    """
    found = world_field(rec)
    if found is None:
        return None
    if rec.pos is not None:
        return position_fit([found], [world_positions(rec)])["rms"]
    field, orientation, rate = found
    n = len(field)

    def regressors(bases) -> np.ndarray:
        # (3 n, len(bases) * 3): basis matrix times the k-th column of R, stacked over samples
        return np.column_stack(
            [
                np.einsum("ij,nj->ni", b, orientation[:, :, k]).ravel()
                for b in bases
                for k in range(3)
            ]
        )

    board = np.column_stack([
        np.tile(np.eye(3), (n, 1)), regressors(BOARD_BASIS), np.cross(rate, field).ravel(),
    ])  # fmt: skip
    y = field.ravel()
    left = y - board @ np.linalg.lstsq(board, y, rcond=None)[0]
    gradient = regressors(GRADIENT_BASIS)
    gradient = gradient - board @ np.linalg.lstsq(board, gradient, rcond=None)[0]
    part = (gradient @ np.linalg.lstsq(gradient, left, rcond=None)[0]).reshape(n, 3)
    part -= part.mean(axis=0)
    return float(np.sqrt(np.mean(np.sum(part**2, axis=1))))


def estimate_world_magnetic(session: Mapping, half) -> Estimate | None:
    """Gradient ``G`` and arm ``r`` of a field fixed in the world (the simulator's model).

    The world field (twin's axes) is regressed on an offset per recording, the entries of
    ``R`` (B -> world) and a lag (:func:`_field_fit`): ``C_i,jk = G_ij r_k`` for the model.
    ``C`` is brought to that form by its best rank-one factor (the SVD of ``C`` arranged as
    (ij) x k), ``G`` made symmetric and traceless (a static field in free space; this also
    leaves out a residual hard iron, ``G = I``), then ``r`` and ``G`` are refitted in turn by
    least squares. ``|r|`` is set to the simulator's realistic arm (only ``G r`` is
    observable). Detection: the RMS of ``G R r`` about its mean (normalised field).
    """
    recordings = [rec for rec in _halves(session, half) if world_field(rec) is not None]
    if not recordings:
        return None
    parts = [world_field(rec, tilt=True) for rec in recordings]
    if all(rec.pos is not None for rec in recordings):
        return _estimate_from_positions(parts, [world_positions(r, True) for r in recordings])
    offsets, coef, lag, field, orientation = _field_fit(parts)
    c = coef.reshape(3, 3, 3)  # [j, k, i]: R_jk -> field_i
    tensor = np.transpose(c, (2, 0, 1)).reshape(9, 3)  # rows (i, j), columns k
    u, s, vt = np.linalg.svd(tensor)
    g = (u[:, 0] * s[0]).reshape(3, 3)
    r = vt[0]
    y = field - offsets - lag
    basis = [gradient_matrix(*e) for e in np.eye(5)]
    for _ in range(10):
        g = 0.5 * (g + g.T) - np.trace(g) / 3.0 * np.eye(3)
        a = g[None] @ orientation  # (n, 3, 3): r -> G R r
        r = np.linalg.lstsq(a.reshape(-1, 3), y.ravel(), rcond=None)[0]
        p = orientation @ r  # positions, (n, 3)
        cols = np.stack([(p @ b.T).ravel() for b in basis], axis=1)
        g = gradient_matrix(*np.linalg.lstsq(cols, y.ravel(), rcond=None)[0])
    arm = np.linalg.norm(WorldMagnetic().arm())
    scale = np.linalg.norm(r) / arm if np.linalg.norm(r) > 0 else 1.0
    r, g = r / scale, g * scale
    part = (orientation @ r) @ g.T
    part -= part.mean(axis=0)
    params = {
        "arm_x_m": float(r[0]), "arm_y_m": float(r[1]), "arm_z_m": float(r[2]),
        "grad_xx": float(g[0, 0]), "grad_yy": float(g[1, 1]), "grad_xy": float(g[0, 1]),
        "grad_xz": float(g[0, 2]), "grad_yz": float(g[1, 2]),
    }  # fmt: skip
    return Estimate(params, float(np.sqrt(np.mean(np.sum(part**2, axis=1)))))


def _estimate_from_positions(parts: list, positions: list) -> Estimate:
    """``world_magnetic``'s parameters where the positions are known: the gradient and the
    dipole of :func:`position_fit` in the twin's world (the arm is not read then).
    Detection: the fit's ``rms``."""
    fit = position_fit(parts, positions)
    g, centre, moment = fit["gradient"], fit["centre"], fit["moment"]
    centre = np.zeros(3) if centre is None else centre
    params = {
        "grad_xx": float(g[0, 0]), "grad_yy": float(g[1, 1]), "grad_xy": float(g[0, 1]),
        "grad_xz": float(g[0, 2]), "grad_yz": float(g[1, 2]),
        "dipole_x_m": float(centre[0]), "dipole_y_m": float(centre[1]),
        "dipole_z_m": float(centre[2]), "moment_x": float(moment[0]),
        "moment_y": float(moment[1]), "moment_z": float(moment[2]),
    }  # fmt: skip
    return Estimate(params, fit["rms"])


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
    found = [shock_events(rec) for rec in _halves(session, half)]
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
    power = line_power(_halves(session, half), freq)
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
