"""Which orientations a set of static poses shows gravity in, and what the cube fit can learn.

The cube fit (eq. 32, :func:`imucal.fits.accelerometer.fit_cube`) fits ``|U (a - o)| = g`` with
9 unknowns. Counting static segments does not tell whether they determine them: a recording
left in three poses for a day, with dozens of handling pauses at the same three orientations,
has many segments but only three gravity directions. What matters is the set of *distinct*
directions: near the nominal model (``U = I``, ``o = 0``, ``a = g u``) the residual of a pose
moves with the parameters as

    d|U (a - o)| = g (u_x^2 dU_xx + u_y^2 dU_yy + u_z^2 dU_zz + u_x u_y dU_xy + u_x u_z dU_xz
                      + u_y u_z dU_yz) - (u_x do_x + u_y do_y + u_z do_z),

one row ``[u_x^2, u_y^2, u_z^2, u_x u_y, u_x u_z, u_y u_z, u_x, u_y, u_z]`` per orientation. The
9 parameters are identifiable when these rows have rank 9 and are not nearly dependent. Two
things make them so: directions of both signs along each axis (``u_k^2`` and ``u_k`` are then
independent: a bias is told from a scale), and directions between the axes (the cross terms;
the protocol's 45-degree V-block positions). Six faces alone give rank 6; three one-sided poses
rank 3.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from imucal.columns import AXES

#: Gravity directions closer than this (deg) are one orientation: the pauses of a hand-held or
#: handled recording at one pose scatter by a few degrees (up to about 6 deg on the CATS tag).
ORIENTATION_TOL_DEG = 15.0
#: Largest condition number of the column-normalised design over the distinct orientations
#: for an identifiable cube fit. The protocol's 12 positions give 2.4, nine random directions
#: over the sphere about 200, directions confined to one octant (one sign on every axis) 400 to
#: 2500: a relative error of the pose means is amplified up to this factor in the parameters.
MAX_CONDITION = 1000.0
#: The cube fit's unknowns (``S'`` upper-triangular and ``o``): one orientation each at least.
UNKNOWNS = 9
#: A direction's component along an axis beyond this counts as gravity on that side of the
#: axis (within 60 deg of it).
SIDE_COMPONENT = 0.5


@dataclass(frozen=True)
class OrientationCoverage:
    """The distinct gravity directions of a set of static poses and what they determine.

    Attributes
    ----------
    directions : ndarray, shape (k, 3)
        Unit direction of each distinct orientation (the sample-weighted mean of its poses'
        mean readings, normalised), in the sensor frame.
    members : tuple of tuple of int
        Indices of the poses of each orientation.
    sides : dict of str to list of str
        Axis -> the signs (``'+'``, ``'-'``) along which some orientation sees gravity.
    condition : float
        Condition number of the column-normalised linearised design (inf when rank < 9).
    rank : int
        Numerical rank of that design.
    identifiable : bool
        At least :data:`UNKNOWNS` orientations, rank 9 and ``condition <= MAX_CONDITION``.
    reason : str
        What the poses show and, when not identifiable, what the fit would need ("" when it is).
    """

    directions: np.ndarray
    members: tuple
    sides: dict
    condition: float
    rank: int
    identifiable: bool
    reason: str

    def to_dict(self) -> dict:
        return {
            "orientations": len(self.directions),
            "directions": np.round(self.directions, 4).tolist(),
            "poses_per_orientation": [len(m) for m in self.members],
            "sides": self.sides,
            "condition": self.condition if np.isfinite(self.condition) else None,
            "rank": self.rank,
            "identifiable": self.identifiable,
            "reason": self.reason,
        }


def distinct_orientations(
    means: np.ndarray, counts: np.ndarray | None = None, *, tol_deg: float = ORIENTATION_TOL_DEG
) -> tuple[np.ndarray, tuple]:
    """Group pose means into orientations whose gravity directions are within ``tol_deg``.

    Parameters
    ----------
    means : ndarray, shape (n, 3)
        Mean accelerometer reading of each pose (any unit; only the direction counts).
    counts : ndarray, shape (n,), optional
        Samples per pose: the longest pose of a group is its seed and the weights of its mean.
    tol_deg : float
        Largest angle (deg) between a pose and its orientation's seed.

    Returns
    -------
    directions : ndarray, shape (k, 3)
        Unit direction per orientation, longest orientation first.
    members : tuple of tuple of int
        Pose indices per orientation.

    Raises
    ------
    ValueError
        If ``means`` is not (n, 3) finite with non-zero rows, or ``counts`` does not match.
    """
    means = np.asarray(means, dtype=float)
    if means.ndim != 2 or means.shape[1] != 3 or not np.all(np.isfinite(means)):
        raise ValueError(f"pose means: expected a finite (n, 3) array, got shape {means.shape}")
    norm = np.linalg.norm(means, axis=1)
    if np.any(norm == 0):
        raise ValueError("pose means: a zero vector has no direction; expected readings at rest")
    counts = np.ones(len(means)) if counts is None else np.asarray(counts, dtype=float)
    if counts.shape != (len(means),):
        raise ValueError(f"{counts.shape} counts for {len(means)} pose means; expected one each")
    unit = means / norm[:, None]
    cos_tol = np.cos(np.radians(tol_deg))
    seeds: list[int] = []
    groups: list[list[int]] = []
    for i in np.argsort(-counts, kind="stable"):
        for seed, group in zip(seeds, groups):
            if unit[i] @ unit[seed] >= cos_tol:
                group.append(int(i))
                break
        else:
            seeds.append(int(i))
            groups.append([int(i)])
    directions = np.array([(counts[g, None] * unit[g]).sum(axis=0) for g in groups])
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    return directions.reshape(-1, 3), tuple(tuple(sorted(g)) for g in groups)


def cube_design(directions: np.ndarray) -> np.ndarray:
    """Linearised cube-fit design, one row per direction, shape (k, 9) (module docstring)."""
    x, y, z = np.asarray(directions, dtype=float).T
    return np.column_stack([x * x, y * y, z * z, x * y, x * z, y * z, x, y, z])


def cube_coverage(
    means: np.ndarray, counts: np.ndarray | None = None, *, tol_deg: float = ORIENTATION_TOL_DEG
) -> OrientationCoverage:
    """Whether static poses determine the cube fit's 9 parameters, judged by their directions.

    Parameters
    ----------
    means : ndarray, shape (n, 3)
        Mean accelerometer reading of each pose (m/s^2, sensor frame).
    counts : ndarray, shape (n,), optional
        Samples per pose.
    tol_deg : float
        Poses within this angle (deg) are one orientation (:func:`distinct_orientations`).

    Returns
    -------
    OrientationCoverage
    """
    if len(means) == 0:
        reason = (
            "no static pose to fit; the cube fit (eq. 32) needs at least "
            f"{UNKNOWNS} distinct orientations spanning both signs of each axis"
        )
        return OrientationCoverage(np.zeros((0, 3)), (), {}, np.inf, 0, False, reason)
    directions, members = distinct_orientations(means, counts, tol_deg=tol_deg)
    sides = {
        a: [
            s
            for s, sign in (("+", 1.0), ("-", -1.0))
            if np.any(sign * directions[:, k] > SIDE_COMPONENT)
        ]
        for k, a in enumerate(AXES)
    }
    design = cube_design(directions)
    scale = np.linalg.norm(design, axis=0)
    sv = np.linalg.svd(design / np.where(scale > 0, scale, 1.0), compute_uv=False)
    rank = int(np.sum(sv > 1e-12 * sv[0]))
    condition = float(sv[0] / sv[-1]) if rank == UNKNOWNS else np.inf
    identifiable = len(directions) >= UNKNOWNS and condition <= MAX_CONDITION
    found = ", ".join(_name(d) for d in directions)
    one_sided = [
        f"{a} ({'only ' + s[0] if s else 'neither'})" for a, s in sides.items() if len(s) < 2
    ]
    reason = ""
    if not identifiable:
        reason = (
            f"the {sum(len(m) for m in members)} static poses show gravity in "
            f"{len(directions)} distinct orientation(s) ({found}; poses within "
            f"{tol_deg:g} deg are one), rank {rank} of the {UNKNOWNS} parameters"
            + (
                f", condition number {condition:.3g} > {MAX_CONDITION:g}"
                if rank == UNKNOWNS
                else ""
            )
            + (f"; one-sided axes: {', '.join(one_sided)}" if one_sided else "")
            + f". The cube fit (eq. 32) needs at least {UNKNOWNS} distinct orientations spanning "
            "both signs of each axis and directions between the axes (the protocol: six faces "
            "and six 45-degree V-block positions)"
        )
    return OrientationCoverage(directions, members, sides, condition, rank, identifiable, reason)


def _name(direction: np.ndarray) -> str:
    """'-z' for a direction within 20 deg of an axis, else the rounded vector."""
    k = int(np.argmax(np.abs(direction)))
    if abs(direction[k]) >= np.cos(np.radians(20.0)):
        return f"{'+' if direction[k] > 0 else '-'}{AXES[k]}"
    return "(" + ", ".join(f"{v:+.2f}" for v in direction) + ")"
