"""Mounting of the reference: the rotation ``R`` with ``v_B = R @ v_ref``.

Estimated from the time-aligned gyroscope and accelerometer vectors (weighted Wahba problem,
solved with an SVD).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

#: The mounting convention of :class:`Mounting`, written into the JSON result.
MOUNTING_CONVENTION = "v_B = R @ v_ref; R = Rotation.from_rotvec(rotvec_rad)"


# --------------------------------------------------------------------------- mounting


@dataclass(frozen=True)
class Mounting:
    """Rotation from the reference's axes to frame B: ``v_B = matrix @ v_ref``.

    Attributes
    ----------
    matrix : ndarray, shape (3, 3)
    rotvec_rad : ndarray, shape (3,)
    angle_deg, angle_std_deg : float
        Rotation angle and the RMS uncertainty of the rotation vector (formal, white residuals).
    residual_rms : dict
        Per sensor ('acc', 'gyr'): RMS per component of ``v_B - R v_ref`` (m/s^2, rad/s).
    n_samples : dict
        Per sensor: vector pairs used.
    """

    matrix: np.ndarray
    rotvec_rad: np.ndarray
    angle_deg: float
    angle_std_deg: float
    residual_rms: dict
    n_samples: dict

    def to_dict(self) -> dict:
        return {
            "convention": MOUNTING_CONVENTION,
            "matrix": self.matrix.tolist(),
            "rotvec_rad": self.rotvec_rad.tolist(),
            "angle_deg": self.angle_deg,
            "angle_std_deg": self.angle_std_deg,
            "residual_rms": dict(self.residual_rms),
            "n_samples": dict(self.n_samples),
        }


def _wahba(b: np.ndarray, r: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Rotation R minimising sum w |b - R r|^2 (Kabsch / Markley SVD)."""
    h = (b * w[:, None]).T @ r
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(u @ vt))
    return u @ np.diag([1.0, 1.0, d]) @ vt


def estimate_mounting(
    vectors_module: dict[str, np.ndarray], vectors_reference: dict[str, np.ndarray]
) -> Mounting:
    """Mounting rotation from time-aligned vector pairs (weighted Wahba problem).

    Parameters
    ----------
    vectors_module : dict of str to ndarray, shape (n_s, 3)
        Calibrated module vectors in frame B per sensor (e.g. 'acc' in m/s^2, 'gyr' in rad/s).
    vectors_reference : dict of str to ndarray, shape (n_s, 3)
        The reference vectors at the same times, in the reference's axes, same keys.
        Rows with a NaN in either are dropped.

    Returns
    -------
    Mounting

    Raises
    ------
    ValueError
        If the keys or shapes differ, or fewer than 2 non-parallel vectors remain.

    Notes
    -----
    Each sensor is weighted by the inverse variance of its own residual, ``1 / sigma_s^2``,
    which is the maximum-likelihood weighting for isotropic Gaussian residuals. The first pass
    weights each sensor by the inverse of its mean squared norm (equal shares); the second pass
    uses the residuals of the first. ``angle_std_deg`` is ``sqrt(trace(cov))`` of the rotation
    vector with ``cov = (sum_i w_i (|v_i|^2 I - v_i v_i^T))^-1``.
    """
    if set(vectors_module) != set(vectors_reference) or not vectors_module:
        raise ValueError(
            f"module sensors {sorted(vectors_module)} and reference sensors "
            f"{sorted(vectors_reference)} must be the same non-empty set"
        )
    pairs = {}
    for s, values in vectors_module.items():
        b = np.asarray(values, dtype=float)
        r = np.asarray(vectors_reference[s], dtype=float)
        if b.shape != r.shape or b.ndim != 2 or b.shape[1] != 3:
            raise ValueError(
                f"{s}: expected two (n, 3) arrays of equal shape, got {b.shape}, {r.shape}"
            )
        ok = np.all(np.isfinite(b), axis=1) & np.all(np.isfinite(r), axis=1)
        if np.count_nonzero(ok):
            pairs[s] = (b[ok], r[ok])
    if sum(len(b) for b, _ in pairs.values()) < 2:
        raise ValueError("fewer than 2 finite vector pairs; expected enough to fix a rotation")
    weight = {s: 1.0 / np.mean(np.sum(r * r, axis=1)) for s, (_, r) in pairs.items()}
    for _ in range(2):
        b_all = np.vstack([b for b, _ in pairs.values()])
        r_all = np.vstack([r for _, r in pairs.values()])
        w_all = np.concatenate([np.full(len(b), weight[s]) for s, (b, _) in pairs.items()])
        rot = _wahba(b_all, r_all, w_all)
        rms = {s: float(np.sqrt(np.mean((b - r @ rot.T) ** 2))) for s, (b, r) in pairs.items()}
        weight = {s: 1.0 / max(rms[s], 1e-12) ** 2 for s in pairs}
    v = r_all @ rot.T
    info = np.zeros((3, 3))
    for s, (_, r) in pairs.items():
        vs = r @ rot.T
        info += weight[s] * (np.sum(vs * vs) * np.eye(3) - vs.T @ vs)
    if np.linalg.matrix_rank(info) < 3 or v.shape[0] < 2:
        raise ValueError("the vector pairs are all parallel; the mounting is not observable")
    cov = np.linalg.inv(info)
    rotvec = Rotation.from_matrix(rot).as_rotvec()
    return Mounting(
        matrix=rot,
        rotvec_rad=rotvec,
        angle_deg=float(np.degrees(np.linalg.norm(rotvec))),
        angle_std_deg=float(np.degrees(np.sqrt(np.trace(cov)))),
        residual_rms=rms,
        n_samples={s: len(b) for s, (b, _) in pairs.items()},
    )
