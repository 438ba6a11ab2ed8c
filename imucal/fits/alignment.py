"""The rotation ``T_R`` from the sensor to the platform frame B, from the rotation3d phases.

Frame B is spanned by the platform's rotation axes: during phase ``x`` the module turns about x of
B, and so on. After step 1 a sensor's output ``v' = S'(r - o)`` is metrically correct but still
rotated by ``T_R`` (eq. 16); ``T_R`` follows from what the phases imply in frame B:

* **constant component** (magnetometer eqs. 25-27, accelerometer): a vector fixed in the world
  (field, gravity) turns about x of B during phase x, so row x of ``T_R`` gives a constant value
  ``T_R[x] . v'_k``. Each phase fixes its row of ``T_R`` up to sign, i.e. the rotation up to a
  turn about the phase axis: one phase leaves the angle about its own axis free, two phases with
  distinct axes fix ``T_R`` completely, three over-determine it.
* **rotation axis** (gyroscope eqs. 28-31): the rate during phase x is along x of B, so the other
  two rows give zero. The same identifiability holds (a phase is blind to a turn about its axis).

Two ways each: the paper's (a few points per phase: the extremes of the rotating components, or
the rates at 1/3 and 2/3 of the phase) and the full-phase way (all samples of each phase). Both
use the exact rotation (rotation vector ``alpha``) by default; ``exact=False`` fits the paper's
small-angle matrix ``I + [alpha]_x`` of eq. 5 instead.

Assumption: ``T_R`` is closer to the identity than 90 degrees about any axis (signs of the phase
directions are taken from the phase's own axis component).

The paper's and the full-phase ways to ``T_R`` share the phase samples and the sandwich
covariance, so they are kept side by side.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.optimize import least_squares

from imucal.columns import AXES, TIME, column_values, row_bounds, sensor_columns
from imucal.errormodel import rotation_matrix

METHODS = ("full", "paper")
#: Phase-segment kind and labels in the segments table.
PHASE_KIND = "phase"


@dataclass(frozen=True)
class AlignmentResult:
    """``T_R`` estimated from the rotation3d phases.

    Attributes
    ----------
    matrix : ndarray, shape (3, 3)
        ``T_R``: ``rotation_matrix(alpha_rad, exact)``; calibrated = ``matrix @ v'``.
    alpha_rad : ndarray, shape (3,)
        Rotation vector (exact) or small angles (eq. 5) in rad.
    std_alpha_rad : ndarray, shape (3,)
        'full': the sandwich covariance of the residuals, which allows for their correlation in
        time (:func:`sandwich_covariance`); 'paper': ``sigma^2 (J^T J)^-1`` with ``sigma^2`` from
        the spread over the phases. Counts the noise of the phase samples only, not the
        uncertainty of step 1 (:mod:`imucal.fits.propagation` adds it).
    covariance : ndarray, shape (3, 3)
        Covariance of ``alpha_rad``.
    residual_rms : dict of str to float
        Per used phase: RMS of the method's own residuals (unit of the input vectors).
    spread : dict of str to float
        Per used phase, the same for both methods: RMS about zero (rotation axis) or about its
        mean (constant component) of the components that the phase must leave constant / zero,
        over all samples after alignment (unit of the input vectors).
    used_points : dict of str to ndarray of int
        Per used phase, indices into that phase's array of the samples the method used.
    skipped : dict of str to str
        Phases given but not used, with the reason.
    method : str
        'full' or 'paper'.
    exact : bool
    condition : str
        'constant_component' or 'rotation_axis'.
    """

    matrix: np.ndarray
    alpha_rad: np.ndarray
    std_alpha_rad: np.ndarray
    covariance: np.ndarray
    residual_rms: dict
    spread: dict
    used_points: dict
    skipped: dict
    method: str
    exact: bool
    condition: str

    def apply(self, vectors: np.ndarray) -> np.ndarray:
        """Rotate step-1 output ``v'`` (shape (n, 3)) into frame B: ``matrix @ v'`` per row."""
        return np.asarray(vectors, dtype=float) @ self.matrix.T

    def to_dict(self) -> dict:
        return {
            "matrix": self.matrix.tolist(),
            "alpha_rad": self.alpha_rad.tolist(),
            "std_alpha_rad": self.std_alpha_rad.tolist(),
            "covariance": self.covariance.tolist(),
            "residual_rms": dict(self.residual_rms),
            "spread": dict(self.spread),
            "used_points": {k: v.tolist() for k, v in self.used_points.items()},
            "skipped": dict(self.skipped),
            "method": self.method,
            "exact": self.exact,
            "condition": self.condition,
        }


def _check_phases(phases: dict, method: str) -> dict[str, np.ndarray]:
    if method not in METHODS:
        raise ValueError(f"unknown alignment method {method!r}; expected one of {METHODS}")
    out = {}
    for label, values in phases.items():
        if label not in AXES:
            raise ValueError(f"unknown phase label {label!r}; expected one of {AXES}")
        v = np.asarray(values, dtype=float)
        if v.ndim != 2 or v.shape[1] != 3:
            raise ValueError(f"phase {label!r}: expected shape (n, 3), got {v.shape}")
        bad = np.flatnonzero(~np.isfinite(v).all(axis=1))
        if bad.size:
            raise ValueError(
                f"phase {label!r}: {bad.size} samples are not finite, first at index {bad[0]}: "
                f"{v[bad[0]].tolist()}; expected finite vectors (drop rows without a sample)"
            )
        out[label] = v
    return out


def _require_two(used: dict, skipped: dict, condition: str) -> None:
    """Refuse fewer than two usable phases: one phase cannot see a turn about its own axis."""
    if len(used) >= 2:
        return
    detail = "; ".join(f"{k}: {v}" for k, v in skipped.items()) or "none given"
    if not used:
        raise ValueError(
            f"no usable phase for the {condition} alignment (skipped: {detail}); expected at "
            "least two phases whose axes differ"
        )
    (only,) = used
    raise ValueError(
        f"only phase {only!r} is usable for the {condition} alignment (skipped: {detail}): the "
        f"rotation about {only} is not identifiable from it; expected at least two phases"
    )


def _blocks(lengths: list[int], per_sample: int) -> list[np.ndarray]:
    """Row indices (n_i, per_sample) of each phase's samples in the concatenated residuals."""
    out, start = [], 0
    for n in lengths:
        out.append(start + np.arange(n * per_sample).reshape(n, per_sample))
        start += n * per_sample
    return out


def _wahba(body: list[np.ndarray], axes: list[int], weights: list[float]) -> np.ndarray:
    """Rotation R maximising sum w_i e_axis_i . (R n_i) (Wahba's problem, SVD solution)."""
    b = np.zeros((3, 3))
    for n, a, w in zip(body, axes, weights):
        b[a] += w * n
    u, _, vt = np.linalg.svd(b)
    d = np.diag([1.0, 1.0, np.linalg.det(u @ vt)])
    return u @ d @ vt


def _rotvec(matrix: np.ndarray) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(matrix).as_rotvec()


#: How the 'full' alignment's covariance allows for correlated residuals (for the stage JSONs).
ALIGNMENT_RULE = (
    "sandwich covariance (Newey-West, Bartlett window of 3x the lag where the residuals' "
    "autocorrelation drops below 0.05) scaled by the residuals"
)
#: Largest lag of the residuals' autocorrelation searched for its first drop, as a fraction
#: of a phase's samples.
MAX_LAG_FRACTION = 0.1
#: The autocorrelation has "dropped" below this value.
CORRELATION_FLOOR = 0.05
#: The Bartlett window of the sandwich covariance spans this many times the drop lag.
WINDOW_PER_LAG = 3


def correlation_lag(residuals: np.ndarray) -> int:
    """First lag at which the autocorrelation of ``residuals`` (shape (n, k)) drops below
    :data:`CORRELATION_FLOOR` (0 for white residuals), searched up to
    :data:`MAX_LAG_FRACTION` of n."""
    r = np.asarray(residuals, dtype=float).reshape(len(residuals), -1)
    r = r - r.mean(axis=0)
    var = float(np.sum(r * r))
    if var <= 0:
        return 0
    for lag in range(1, max(1, int(MAX_LAG_FRACTION * len(r))) + 1):
        if float(np.sum(r[lag:] * r[:-lag])) / var < CORRELATION_FLOOR:
            return lag - 1
    return max(1, int(MAX_LAG_FRACTION * len(r)))


def sandwich_covariance(jac: np.ndarray, r: np.ndarray, blocks: list[np.ndarray]) -> np.ndarray:
    """Covariance of least-squares parameters with serially correlated residuals.

    ``(J^T J)^-1 M (J^T J)^-1`` with ``M`` the Newey-West (Bartlett-window) estimate of the
    covariance of the score ``sum_t J_t^T r_t``, per block of consecutive samples (a phase);
    the window is :data:`WINDOW_PER_LAG` times the lag where the residuals' autocorrelation
    drops (:func:`correlation_lag`). White residuals give the plain ``sigma^2 (J^T J)^-1``
    (heteroscedasticity-robust form); low-pass filtered ones, whose neighbours share noise, a
    larger covariance.

    Parameters
    ----------
    jac : ndarray, shape (m, p)
        Jacobian of the residuals at the solution.
    r : ndarray, shape (m,)
        Residuals at the solution.
    blocks : list of ndarray of int, each shape (n_i, k)
        Row indices of the residuals of each sample (k rows per sample), samples in time order.

    Returns
    -------
    ndarray, shape (p, p)
    """
    p = jac.shape[1]
    meat = np.zeros((p, p))
    n_rows = 0
    for rows in blocks:
        scores = np.einsum("nk,nkp->np", r[rows], jac[rows])
        window = WINDOW_PER_LAG * correlation_lag(r[rows])
        meat += scores.T @ scores
        for lag in range(1, min(window, len(scores) - 1) + 1):
            cross = scores[lag:].T @ scores[:-lag]
            meat += (1 - lag / (window + 1)) * (cross + cross.T)
        n_rows += rows.size
    bread = np.linalg.inv(jac.T @ jac)
    # small-sample factor as in sigma^2 = r.r / dof
    return n_rows / max(n_rows - p, 1) * bread @ meat @ bread


def _solve(residuals, alpha0: np.ndarray, n_nuisance: int, what: str, sigma2=None, blocks=None):
    """LM over alpha; covariance ``sigma^2 (J^T J)^-1``; refuse a singular problem.

    ``sigma2`` (variance of one residual) is estimated from the residuals when not given. With
    ``blocks`` (row indices per sample, per phase) the covariance is the sandwich of
    :func:`sandwich_covariance`, for residuals correlated in time.
    """
    res = least_squares(residuals, alpha0, method="lm")
    if not res.success or not np.all(np.isfinite(res.x)):
        raise ValueError(f"{what}: least squares for the alignment angles failed: {res.message}")
    r = res.fun
    dof = r.size - 3 - n_nuisance
    if dof <= 0:
        raise ValueError(f"{what}: {r.size} equations leave no degree of freedom for 3 angles")
    jtj = res.jac.T @ res.jac
    cond = np.linalg.cond(jtj)
    if not np.isfinite(cond) or cond > 1e12:
        raise ValueError(
            f"{what}: the alignment angles are not identifiable from these phases "
            f"(J^T J condition number {cond:.3g}, expected < 1e12)"
        )
    if blocks is not None:
        return res.x, sandwich_covariance(res.jac, r, blocks) * (r.size - 3) / dof
    if sigma2 is None:
        sigma2 = float(r @ r) / dof
    return res.x, sigma2 * np.linalg.inv(jtj)


def _fit_angles(
    residuals,
    normals,
    axes,
    weights,
    n_nuisance,
    what,
    exact,
    spread_of,
    paper_variance_factor=None,
    blocks=None,
):
    """Solve the alignment angles from the Wahba start; return alpha, covariance, T_R, spread.

    With ``paper_variance_factor`` (the paper's few points per phase), the few degrees of
    freedom estimate the noise poorly: the variance of one equation is taken instead as the
    factor times the mean squared spread over all samples of the phases, and the covariance is
    recomputed with it. ``blocks`` (all samples) makes the covariance the sandwich of
    :func:`sandwich_covariance`.
    """
    labels = list(normals)
    start = _rotvec(
        _wahba(
            [normals[lb] for lb in labels],
            [axes[lb] for lb in labels],
            [weights[lb] for lb in labels],
        )
    )
    alpha, cov = _solve(residuals, start, n_nuisance, what, blocks=blocks)
    t = rotation_matrix(alpha, exact)
    spread = spread_of(t)
    if paper_variance_factor is not None:
        sigma2 = paper_variance_factor * float(np.mean(np.square(list(spread.values()))))
        alpha, cov = _solve(residuals, alpha, 0, what, sigma2)
    return alpha, cov, t, spread


def _result(alpha, cov, exact, per_phase_res, spread, used_points, skipped, method, condition):
    return AlignmentResult(
        matrix=rotation_matrix(alpha, exact),
        alpha_rad=np.asarray(alpha, dtype=float),
        std_alpha_rad=np.sqrt(np.diag(cov)),
        covariance=cov,
        residual_rms=per_phase_res,
        spread=spread,
        used_points=used_points,
        skipped=skipped,
        method=method,
        exact=exact,
        condition=condition,
    )


def align_constant_component(
    phases: dict[str, np.ndarray],
    method: str = "full",
    exact: bool = True,
    min_sweep: float = 0.1,
    *,
    correlated: bool = True,
) -> AlignmentResult:
    """``T_R`` such that in phase i the i-th calibrated component stays constant (eqs. 25-27).

    For the magnetometer (step-1-calibrated field) and the accelerometer (low-pass filtered,
    step-1-calibrated specific force; a constant centripetal term during a phase does not
    matter, it only shifts the constant).

    Parameters
    ----------
    phases : dict of str to array_like, shape (n_i, 3)
        Phase label ('x', 'y', 'z' = the platform axis it turns about) -> step-1 output ``v'``
        of the samples in that phase (any unit, e.g. normalised field or m/s^2).
    method : {'full', 'paper'}
        'full': all samples, minimise the variance of the component that must stay constant.
        'paper': per phase the maximum and minimum points of the two rotating components;
        row i of ``T_R`` gives equal values at max/min of component j, at max/min of k and
        (eq. 27 as printed) at max of j and min of k: 3 equations per phase.
    exact : bool
        Exact rotation (rotation vector) or the paper's small-angle matrix (eq. 5).
    min_sweep : float
        A phase is used only if its vectors sweep a circle: ``sqrt(2 lambda_2) / mean|v|`` >=
        ``min_sweep``, with ``lambda_2`` the middle eigenvalue of their covariance (the circle
        radius relative to the norm for a full turn). The accelerometer's phase about the vertical
        axis (gravity does not move) fails this and is skipped and reported.
    correlated : bool
        'full': the covariance allows for residuals correlated in time (sandwich); False
        gives the plain ``sigma^2 (J^T J)^-1`` (cheaper, for refits that only need alpha).

    Returns
    -------
    AlignmentResult

    Raises
    ------
    ValueError
        For an unknown label or method, non-finite samples, fewer than two usable phases (a phase
        cannot see a turn about its own axis), or angles that are not identifiable.

    References
    ----------
    Zhang, Hoeflinger, Reindl (2014), eqs. 16 and 25-27.
    """
    data = _check_phases(phases, method)
    used: dict[str, np.ndarray] = {}
    skipped: dict[str, str] = {}
    normals, weights = {}, {}
    for label, v in data.items():
        if v.shape[0] < 4:
            skipped[label] = f"{v.shape[0]} samples, expected at least 4"
            continue
        lam, vec = np.linalg.eigh(np.cov(v.T))
        sweep = float(np.sqrt(2 * max(lam[1], 0.0)) / np.mean(np.linalg.norm(v, axis=1)))
        if sweep < min_sweep:
            skipped[label] = f"sweep {sweep:.3g} < min_sweep {min_sweep:g} (vector does not turn)"
            continue
        a = AXES.index(label)
        n = vec[:, 0] * np.sign(vec[a, 0])  # circle-plane normal, sign of its own axis
        used[label], normals[label], weights[label] = v, n, v.shape[0] * lam[1]
    _require_two(used, skipped, "constant-component")

    axes = {label: AXES.index(label) for label in used}
    if method == "full":
        centred = {label: v - v.mean(axis=0) for label, v in used.items()}
        points = {label: np.arange(v.shape[0]) for label, v in used.items()}
        n_nuisance = len(used)  # one constant per phase
    else:
        centred, points = {}, {}
        for label, v in used.items():
            j, k = (b for b in range(3) if b != axes[label])
            idx = np.array([v[:, j].argmax(), v[:, j].argmin(), v[:, k].argmax(), v[:, k].argmin()])
            p = v[idx]
            # eqs. 25, 26, 27: T_i . (p_a - p_b) = 0
            centred[label] = np.array([p[0] - p[1], p[2] - p[3], p[0] - p[3]])
            points[label] = idx
            chord_normal = np.cross(p[0] - p[1], p[2] - p[3])
            normals[label] = chord_normal * np.sign(chord_normal[axes[label]])
        n_nuisance = 0

    def residuals(alpha: np.ndarray) -> np.ndarray:
        t = rotation_matrix(alpha, exact)
        return np.concatenate([centred[lb] @ t[axes[lb]] for lb in used])

    def spread_of(t: np.ndarray) -> dict[str, float]:
        return {lb: float(np.std(v @ t[axes[lb]])) for lb, v in used.items()}

    # 'paper': one equation is a difference of two samples, twice the variance of one sample
    alpha, cov, t, spread = _fit_angles(
        residuals,
        {lb: normals[lb] / np.linalg.norm(normals[lb]) for lb in used},
        axes,
        weights,
        n_nuisance,
        f"constant-component alignment ({method}, phases {sorted(used)})",
        exact,
        spread_of,
        paper_variance_factor=2.0 if method == "paper" else None,
        blocks=(
            _blocks([len(centred[lb]) for lb in used], 1)
            if method == "full" and correlated
            else None
        ),
    )
    own = {lb: float(np.sqrt(np.mean((centred[lb] @ t[axes[lb]]) ** 2))) for lb in used}
    return _result(alpha, cov, exact, own, spread, points, skipped, method, "constant_component")


def align_rotation_axis(
    phases: dict[str, np.ndarray],
    method: str = "full",
    exact: bool = True,
    min_rms_rate: float = 0.1,
    *,
    correlated: bool = True,
) -> AlignmentResult:
    """``T_R`` such that in phase i the rate has no component off axis i (eqs. 28-31).

    For the gyroscope (bias-free, step-1-calibrated, optionally low-pass filtered rates).

    Parameters
    ----------
    phases : dict of str to array_like, shape (n_i, 3)
        Phase label ('x', 'y', 'z' = the platform axis it turns about) -> rates ``w'`` in that
        phase, rad/s.
    method : {'full', 'paper'}
        'full': all samples; minimise the sum of squares of the two off-axis calibrated rates,
        started from the Wahba (SVD) solution that turns each phase's dominant rate direction onto
        its axis. 'paper': the samples at 1/3 and 2/3 of the phase, the two off-axis rows give zero
        (eqs. 28-31): 4 equations per phase.
    exact : bool
        Exact rotation (rotation vector) or the paper's small-angle matrix (eq. 5).
    min_rms_rate : float
        A phase is used only if the RMS of its rate along the dominant direction is at least this,
        rad/s (the platform turns).
    correlated : bool
        As for :func:`align_constant_component`.

    Returns
    -------
    AlignmentResult

    Raises
    ------
    ValueError
        For an unknown label or method, non-finite samples, fewer than two usable phases (a phase
        cannot see a turn about its own axis), or angles that are not identifiable.

    References
    ----------
    Zhang, Hoeflinger, Reindl (2014), eqs. 28-31.
    """
    data = _check_phases(phases, method)
    used: dict[str, np.ndarray] = {}
    skipped: dict[str, str] = {}
    normals, weights = {}, {}
    for label, w in data.items():
        if w.shape[0] < 3:
            skipped[label] = f"{w.shape[0]} samples, expected at least 3"
            continue
        lam, vec = np.linalg.eigh(w.T @ w / w.shape[0])
        rms = float(np.sqrt(max(lam[2], 0.0)))
        if rms < min_rms_rate:
            skipped[label] = f"RMS rate {rms:.3g} rad/s < min_rms_rate {min_rms_rate:g} rad/s"
            continue
        a = AXES.index(label)
        used[label], normals[label], weights[label] = w, vec[:, 2] * np.sign(vec[a, 2]), lam[2]
    _require_two(used, skipped, "rotation-axis")

    axes = {label: AXES.index(label) for label in used}
    off = {label: [b for b in range(3) if b != axes[label]] for label in used}
    if method == "full":
        points = {label: np.arange(w.shape[0]) for label, w in used.items()}
    else:
        points = {
            label: np.array([w.shape[0] // 3, (2 * w.shape[0]) // 3]) for label, w in used.items()
        }
    chosen = {label: used[label][points[label]] for label in used}

    def residuals(alpha: np.ndarray) -> np.ndarray:
        t = rotation_matrix(alpha, exact)
        # eqs. 28-31: the off-axis rows of T_R give zero
        return np.concatenate([(chosen[lb] @ t[off[lb]].T).ravel() for lb in used])

    def spread_of(t: np.ndarray) -> dict[str, float]:
        return {lb: float(np.sqrt(np.mean((w @ t[off[lb]].T) ** 2))) for lb, w in used.items()}

    alpha, cov, t, spread = _fit_angles(
        residuals,
        normals,
        axes,
        weights,
        0,
        f"rotation-axis alignment ({method}, phases {sorted(used)})",
        exact,
        spread_of,
        paper_variance_factor=1.0 if method == "paper" else None,
        blocks=(
            _blocks([len(chosen[lb]) for lb in used], 2)
            if method == "full" and correlated
            else None
        ),
    )
    own = {lb: float(np.sqrt(np.mean((chosen[lb] @ t[off[lb]].T) ** 2))) for lb in used}
    return _result(alpha, cov, exact, own, spread, points, skipped, method, "rotation_axis")


def phase_samples(
    table: pd.DataFrame, segments: pd.DataFrame, sensor: str, recording: str = "rotation3d"
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Cut the rotation3d phases out of an ingested recording.

    Parameters
    ----------
    table : DataFrame
        Ingested recording (``t_s`` and the sensor's three columns).
    segments : DataFrame
        Segments table (docs/architecture.md): rows of kind 'phase' of ``recording`` with labels
        'x', 'y', 'z' and ``start_index``/``end_index`` (end exclusive) into ``table``.
    sensor : str
        'acc', 'gyr' or 'mag'; rows where its columns are NaN (no fresh sample) are dropped.
    recording : str

    Returns
    -------
    dict of str to (ndarray (n_i,), ndarray (n_i, 3))
        Phase label -> (timestamps in s, sensor values).

    Raises
    ------
    ValueError
        If the segments hold no phase of ``recording``, a phase label is unknown or repeated, its
        indices fall outside the table, or a phase has no sample.
    """
    cols = sensor_columns(sensor)
    rows = segments[(segments["recording"] == recording) & (segments["kind"] == PHASE_KIND)]
    if rows.empty:
        raise ValueError(
            f"the segments table has no rows of kind {PHASE_KIND!r} for recording {recording!r}; "
            "expected the phases x, y, z of the rotation3d recording"
        )
    out: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for label, (start, end) in zip(
        rows["label"].astype(str).tolist(), row_bounds(rows), strict=True
    ):
        if label not in AXES or label in out:
            raise ValueError(
                f"phase label {label!r} of {recording!r} is unknown or repeated; expected each of "
                f"{AXES} at most once"
            )
        if not 0 <= start < end <= len(table):
            raise ValueError(
                f"phase {label!r} of {recording!r} spans rows [{start}, {end}), expected within "
                f"[0, {len(table)}) of the ingested table"
            )
        values = column_values(table, cols, slice(start, end))
        keep = ~np.isnan(values).any(axis=1)
        if not keep.any():
            raise ValueError(
                f"phase {label!r} of {recording!r} (rows [{start}, {end})) has no {sensor} sample"
            )
        out[label] = (table[TIME].to_numpy(dtype=float)[start:end][keep], values[keep])
    return out
