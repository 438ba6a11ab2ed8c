"""The world field of a hand-held or robot recording against its orientation reference: the
``world_magnetic`` disturbance of the simulator (:mod:`imucal.sim.effects.disturbance`), its
statistics and its estimator.

The field carried into the world by the reference's orientation is constant in a clean
recording; a field fixed in the world near the path makes it follow the sensor's position.
Where the reference reports the position (``pos``, m), the world field is fitted as a function
of it (:func:`position_fit`: a uniform gradient, and a dipole with its centre free where it
predicts held-out blocks better); statistic ``field_position_rms``: the RMS of that part.
Without a position, a module turned about a pivot (wrist, flange) has its position linear in
the entries of its orientation matrix, and the statistic is the RMS of the world field's part
linear in those entries (a field that follows the position, not the attitude, is then not
seen). A magnetometer lag makes the world field follow the rate (fitted beside it,
:func:`_field_fit`), the reference's noise and jitter make it scatter; neither is a function of
the position or linear in the attitude.

The functions read recordings as :class:`imucal.gap.motionstats.MotionRecording` holds them.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from imucal.gap.effects import Estimate
from imucal.orientation import up_vector
from imucal.sim.effects import WorldMagnetic
from imucal.sim.effects.disturbance import dipole_field, gradient_matrix

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


def recording_halves(session: Mapping, half) -> list:
    """Each recording of a session cut to its half ``A`` or ``B`` (``None``: the whole), as a
    list."""
    return [rec.half(half) for rec in session.values()]


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
    recordings = [rec for rec in recording_halves(session, half) if world_field(rec) is not None]
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
