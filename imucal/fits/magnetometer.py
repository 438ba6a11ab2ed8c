"""Magnetometer step 1: ellipsoid fit (Zhang et al. 2014, eqs. 17-24) and its LM refinement.

The raw field ``m`` (sensor frame S, the dataset's unit) lies on an ellipsoid; step 1 finds the
upper-triangular ``S'`` and the bias ``o`` that map it onto the sphere of radius ``field_norm``:

    |S' (m - o)| = field_norm                                            (eqs. 17-18)

The algebraic solution (eqs. 19-24) is the right singular vector of the smallest singular value of
the design matrix ``D``; it is normalised to the quadric ``(m - o)^T A (m - o) = 1`` with ``A``
positive definite, ``o`` from eq. 22 and ``S'`` the upper-triangular Cholesky factor of ``A``
(eq. 21). A Levenberg-Marquardt refinement of eq. 17 over the 9 parameters removes the bias of the
algebraic fit at low coverage. Step 2 (the rotation ``T_R``, eqs. 25-27) is
:func:`calibrate_alignment`, built on :mod:`imucal.fits.alignment`.

The ellipsoid fit, its LM refinement and the covariance of both belong together.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.optimize import least_squares

from imucal import errormodel
from imucal.calibration import SensorCalibration
from imucal.columns import MAG, SI_UNITS, TIME, column_values
from imucal.fits.alignment import ALIGNMENT_RULE, align_constant_component
from imucal.fits.propagation import alignment_sensitivity
from imucal.uncertainty import std_of, two_step_covariance

#: Equal-area partition of the unit sphere for the coverage: bands of equal height in z
#: (equal area by Archimedes' hat-box theorem) times sectors of equal longitude.
COVERAGE_BANDS = 10
COVERAGE_SECTORS = 20

#: Indices of the 6 free entries of the upper-triangular S', row-major.
_UPPER = np.triu_indices(3)


@dataclass(frozen=True)
class EllipsoidSolution:
    """One solution of step 1 (SVD or SVD + LM).

    Attributes
    ----------
    upper : ndarray, shape (3, 3)
        ``S'`` (eq. 16), upper triangular with a positive diagonal; ``|S'(m - o)| = field_norm``.
    bias : ndarray, shape (3,)
        ``o`` in the unit of the readings (eq. 22).
    std_upper : ndarray, shape (3, 3)
        Standard deviation of each entry of ``upper`` (0 below the diagonal), from the Jacobian of
        eq. 17 at this solution: ``sigma^2 (J^T J)^-1`` with ``sigma^2`` from the residuals.
    std_bias : ndarray, shape (3,)
    covariance : ndarray, shape (9, 9)
        Covariance of (the 6 upper entries row-major, then the 3 of ``o``).
    residual_rms : float
        RMS of ``|m'| / field_norm - 1`` (dimensionless, relative to the field norm).
    """

    upper: np.ndarray
    bias: np.ndarray
    std_upper: np.ndarray
    std_bias: np.ndarray
    covariance: np.ndarray
    residual_rms: float

    def to_dict(self) -> dict:
        return {
            "upper": self.upper.tolist(),
            "bias": self.bias.tolist(),
            "std_upper": self.std_upper.tolist(),
            "std_bias": self.std_bias.tolist(),
            "covariance": self.covariance.tolist(),
            "residual_rms": self.residual_rms,
        }

    @classmethod
    def from_dict(cls, d: dict) -> EllipsoidSolution:
        return cls(
            upper=np.asarray(d["upper"], dtype=float),
            bias=np.asarray(d["bias"], dtype=float),
            std_upper=np.asarray(d["std_upper"], dtype=float),
            std_bias=np.asarray(d["std_bias"], dtype=float),
            covariance=np.asarray(d["covariance"], dtype=float),
            residual_rms=float(d["residual_rms"]),
        )


@dataclass(frozen=True)
class EllipsoidFit:
    """Result of step 1: both solutions, which one is used, and the quality of the data.

    Attributes
    ----------
    svd : EllipsoidSolution
        Algebraic solution (eqs. 19-24).
    lm : EllipsoidSolution or None
        Levenberg-Marquardt refinement of eq. 17 started from ``svd``; None when not requested.
    used : str
        'svd+lm' or 'svd': the solution :attr:`upper` and :attr:`bias` return.
    field_norm : float
        Norm of the calibrated field (1 for a normalised magnetometer).
    coverage_pct : float
        Percentage of the cells of an equal-area partition of the sphere
        (:data:`COVERAGE_BANDS` x :data:`COVERAGE_SECTORS`) that hold a step-1-calibrated direction.
    condition_number : float
        Ratio of the largest to the second smallest singular value of the normalised design matrix
        ``D`` (the smallest belongs to the solution): large when the data do not pin down a
        unique quadric (e.g. samples on one or two circles only).
    n_samples : int
        Number of samples in the fit (including accepted extra recordings).
    extra : dict of str to dict
        Per extra recording offered (e.g. 'cube'): ``{"n_samples", "norm_mismatch", "used"}``,
        the relative mismatch of its median step-1 norm from ``field_norm`` under the fit of the
        primary samples, and whether it passed ``max_norm_mismatch`` and joined the fit.
    """

    svd: EllipsoidSolution
    lm: EllipsoidSolution | None
    used: str
    field_norm: float
    coverage_pct: float
    condition_number: float
    n_samples: int
    extra: dict = field(default_factory=dict)

    @property
    def selected(self) -> EllipsoidSolution:
        return self.lm if self.used == "svd+lm" else self.svd

    @property
    def upper(self) -> np.ndarray:
        """``S'`` of the used solution, shape (3, 3)."""
        return self.selected.upper

    @property
    def bias(self) -> np.ndarray:
        """``o`` of the used solution, shape (3,), unit of the readings."""
        return self.selected.bias

    def apply(self, samples: np.ndarray) -> np.ndarray:
        """Step-1-calibrated field ``S'(m - o)``, shape (n, 3), for readings of shape (n, 3)."""
        return errormodel.apply(self.upper, self.bias, samples)

    def to_dict(self) -> dict:
        return {
            "used": self.used,
            "field_norm": self.field_norm,
            "coverage_pct": self.coverage_pct,
            "condition_number": self.condition_number,
            "n_samples": self.n_samples,
            "extra": self.extra,
            "unit": SI_UNITS["mag"],
            "convention": "step1 = upper @ (reading - bias); |step1| = field_norm",
            "svd": self.svd.to_dict(),
            "lm": None if self.lm is None else self.lm.to_dict(),
        }

    @classmethod
    def from_dict(cls, d: dict) -> EllipsoidFit:
        for key in ("used", "field_norm", "svd", "lm"):
            if key not in d:
                raise ValueError(f"magnetometer step-1 result lacks the key {key!r}")
        return cls(
            svd=EllipsoidSolution.from_dict(d["svd"]),
            lm=None if d["lm"] is None else EllipsoidSolution.from_dict(d["lm"]),
            used=d["used"],
            field_norm=float(d["field_norm"]),
            coverage_pct=float(d["coverage_pct"]),
            condition_number=float(d["condition_number"]),
            n_samples=int(d["n_samples"]),
            extra=dict(d.get("extra", {})),
        )


def field_samples(table: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    """Magnetometer samples of an ingested recording: the rows with a fresh sample.

    Parameters
    ----------
    table : DataFrame
        Ingested recording with columns ``t_s`` and ``mag_x..z`` (NaN on rows without a fresh
        magnetometer sample).

    Returns
    -------
    t_s : ndarray, shape (n,)
        Timestamps in s.
    field : ndarray, shape (n, 3)
        Readings in the dataset's magnetometer unit.

    Raises
    ------
    ValueError
        If a column is missing or a row has some but not all three components.
    """
    missing = [c for c in (TIME, *MAG) if c not in table.columns]
    if missing:
        raise ValueError(f"recording lacks the columns {missing}; expected {[TIME, *MAG]}")
    values = column_values(table, MAG)
    nan = np.isnan(values)
    partial = np.flatnonzero(nan.any(axis=1) & ~nan.all(axis=1))
    if partial.size:
        raise ValueError(
            f"{partial.size} rows have some but not all magnetometer components, first at row "
            f"{partial[0]} (t = {table[TIME].iloc[partial[0]]} s); expected all three or none"
        )
    keep = ~nan[:, 0]
    return table[TIME].to_numpy(dtype=float)[keep], values[keep]


def sphere_coverage_pct(directions: np.ndarray) -> float:
    """Percentage of the cells of an equal-area sphere partition that hold a direction.

    Parameters
    ----------
    directions : ndarray, shape (n, 3)
        Vectors (any norm > 0); only their directions count.

    Returns
    -------
    float
        In [0, 100]. The partition has :data:`COVERAGE_BANDS` bands of equal height in z times
        :data:`COVERAGE_SECTORS` sectors of equal longitude (all cells of equal area).
    """
    v = np.asarray(directions, dtype=float)
    u = v / np.linalg.norm(v, axis=1, keepdims=True)
    band = np.clip(((u[:, 2] + 1.0) / 2.0 * COVERAGE_BANDS).astype(int), 0, COVERAGE_BANDS - 1)
    lon = np.arctan2(u[:, 1], u[:, 0])
    sector = np.clip(
        ((lon + np.pi) / (2 * np.pi) * COVERAGE_SECTORS).astype(int), 0, COVERAGE_SECTORS - 1
    )
    cells = np.unique(band * COVERAGE_SECTORS + sector)
    return 100.0 * cells.size / (COVERAGE_BANDS * COVERAGE_SECTORS)


def _design_matrix(m: np.ndarray) -> np.ndarray:
    """``D`` of eq. 19, shape (n, 10), columns as printed."""
    x, y, z = m.T
    return np.column_stack([x * x, x, y * y, y, z * z, z, x * y, y * z, x * z, np.ones_like(x)])


def _quadric_from_d(d: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Quadratic form ``Q``, linear term ``b`` and constant of ``m^T Q m + b^T m + c = 0`` (eq. 20)."""
    q = np.array(
        [
            [d[0], d[6] / 2, d[8] / 2],
            [d[6] / 2, d[2], d[7] / 2],
            [d[8] / 2, d[7] / 2, d[4]],
        ]
    )
    return q, np.array([d[1], d[3], d[5]]), float(d[9])


def _residuals(p: np.ndarray, m: np.ndarray) -> np.ndarray:
    """Eq. 17 residuals ``|S'(m - o)| - 1`` for parameters (6 upper entries, o)."""
    u = np.zeros((3, 3))
    u[_UPPER] = p[:6]
    return np.linalg.norm((m - p[6:]) @ u.T, axis=1) - 1.0


def _jacobian(p: np.ndarray, m: np.ndarray) -> np.ndarray:
    """Analytic Jacobian of :func:`_residuals`, shape (n, 9)."""
    u = np.zeros((3, 3))
    u[_UPPER] = p[:6]
    c = m - p[6:]
    v = c @ u.T
    n = np.linalg.norm(v, axis=1, keepdims=True)
    w = v / n
    # d|v|/dU_ij = w_i c_j ; d|v|/do = -U^T w
    j_upper = np.stack([w[:, i] * c[:, j] for i, j in zip(*_UPPER)], axis=1)
    return np.hstack([j_upper, -w @ u])


def _solution(p: np.ndarray, m: np.ndarray, field_norm: float) -> EllipsoidSolution:
    """Package parameters with the Gauss-Newton covariance of eq. 17 at ``p``."""
    r = _residuals(p, m)
    j = _jacobian(p, m)
    dof = m.shape[0] - p.size
    sigma2 = float(r @ r) / dof
    cov = sigma2 * np.linalg.inv(j.T @ j)
    # the calibrated norm is field_norm: S' scales by it, o does not
    scale = np.concatenate([np.full(6, field_norm), np.ones(3)])
    cov = cov * np.outer(scale, scale)
    std = np.sqrt(np.diag(cov))
    upper = np.zeros((3, 3))
    upper[_UPPER] = p[:6] * field_norm
    std_upper = np.zeros((3, 3))
    std_upper[_UPPER] = std[:6]
    return EllipsoidSolution(
        upper=upper,
        bias=p[6:].copy(),
        std_upper=std_upper,
        std_bias=std[6:],
        covariance=cov,
        residual_rms=float(np.sqrt(np.mean(r * r))),
    )


def _fit(
    samples: np.ndarray,
    refine_lm: bool,
    field_norm: float,
    min_coverage_pct: float,
    max_condition: float,
) -> EllipsoidFit:
    """Step 1 on one set of samples; see :func:`fit_ellipsoid`."""
    m = np.asarray(samples, dtype=float)
    if m.ndim != 2 or m.shape[1] != 3:
        raise ValueError(f"samples must have shape (n, 3), got {m.shape}")
    if m.shape[0] < 10:
        raise ValueError(
            f"need at least 10 magnetometer samples for 9 parameters, got {m.shape[0]}"
        )
    bad = np.flatnonzero(~np.isfinite(m).all(axis=1))
    if bad.size:
        raise ValueError(
            f"{bad.size} magnetometer samples are not finite, first at index {bad[0]}: "
            f"{m[bad[0]].tolist()}; remove rows without a fresh sample first"
        )
    if not np.isfinite(field_norm) or field_norm <= 0:
        raise ValueError(f"field_norm must be a positive number, got {field_norm!r}")

    # normalise (Hartley): m = centre + spread * x
    centre = m.mean(axis=0)
    spread = float(np.sqrt(np.mean(np.sum((m - centre) ** 2, axis=1))))
    if spread == 0:
        raise ValueError(f"all {m.shape[0]} magnetometer samples are equal: {m[0].tolist()}")
    x = (m - centre) / spread

    # eqs. 23-24: d = right singular vector of the smallest singular value
    _, sv, vt = np.linalg.svd(_design_matrix(x), full_matrices=False)
    condition = float(sv[0] / sv[-2]) if sv[-2] > 0 else float("inf")
    # samples that move no more than their noise (a static log: consecutive samples as far
    # apart as any two, and a spread far below the field they sit on) point everywhere about
    # their mean, which covers nothing
    step = np.sqrt(np.mean(np.sum(np.diff(x, axis=0) ** 2, axis=1)))
    static = bool(step > 0.5 * np.sqrt(2.0) and np.linalg.norm(centre) > 10.0 * spread)
    quality = f"(coverage of the sphere {{cov:.1f}} %, condition number {condition:.3g})"
    if static:
        quality = (
            "(the samples do not move beyond their noise, as in a static log: coverage of the "
            f"sphere {{cov:.1f}} %, condition number {condition:.3g})"
        )
    too_little = (
        "the magnetometer samples cover too little of the sphere for an ellipsoid fit "
        + quality
        + f"; expected coverage >= {min_coverage_pct:g} % and condition number <= "
        f"{max_condition:.3g}: rotate the module fully about all three axes"
    )
    # directions of the centred raw samples until an ellipsoid is known
    raw_coverage = 0.0 if static else sphere_coverage_pct(x)
    if static or condition > max_condition:
        raise ValueError(too_little.format(cov=raw_coverage))
    q, b, c = _quadric_from_d(vt[-1])
    if np.trace(q) < 0:
        q, b, c = -q, -b, -c
    eig_q = np.linalg.eigvalsh(q)
    if eig_q[0] <= 0:
        raise ValueError(
            "the magnetometer samples do not describe an ellipsoid: the fitted quadric has "
            f"eigenvalues {eig_q.tolist()} of mixed sign, expected all positive "
            + quality.format(cov=raw_coverage)
            + "; check the coverage of the rotations and magnetic disturbances"
        )
    # eq. 22: centre of the quadric
    o_x = np.linalg.solve(-2.0 * q, b)
    k = float(o_x @ q @ o_x - c)
    if k <= 0:
        raise ValueError(
            f"the fitted quadric is empty (o^T Q o - d10 = {k:.3g}, expected > 0); the samples do "
            "not describe an ellipsoid " + quality.format(cov=raw_coverage)
        )
    a_x = q / k  # (x - o_x)^T a_x (x - o_x) = 1
    upper_x = np.linalg.cholesky(a_x).T  # eq. 21: a_x = U^T U, U upper, diag > 0
    # back to reading units: x - o_x = (m - o) / spread
    upper_svd = upper_x / spread
    bias_svd = centre + spread * o_x

    coverage = sphere_coverage_pct(errormodel.apply(upper_svd, bias_svd, m))
    if coverage < min_coverage_pct:
        raise ValueError(too_little.format(cov=coverage))

    p_svd = np.concatenate([upper_svd[_UPPER], bias_svd])
    svd = _solution(p_svd, m, field_norm)
    lm = None
    if refine_lm:
        res = least_squares(_residuals, p_svd, jac=_jacobian, args=(m,), method="lm", max_nfev=200)
        if not res.success or not np.all(np.isfinite(res.x)):
            # eq. 17 is measured in calibrated units: at low coverage it can shrink S' towards a
            # degenerate (elongated) ellipsoid and run away from the algebraic solution
            raise ValueError(
                f"LM refinement of eq. 17 did not converge ({res.message}); bias moved from "
                f"{bias_svd.tolist()} to {res.x[6:].tolist()} "
                + quality.format(cov=coverage)
                + "; expected better coverage, or use refine_lm=False"
            )
        p_lm = res.x.copy()
        upper_lm = np.zeros((3, 3))
        upper_lm[_UPPER] = p_lm[:6]
        # the cost depends on S' only through S'^T S': restore a positive diagonal
        signs = np.sign(np.diag(upper_lm))
        upper_lm = signs[:, None] * upper_lm
        p_lm[:6] = upper_lm[_UPPER]
        lm = _solution(p_lm, m, field_norm)
    return EllipsoidFit(
        svd=svd,
        lm=lm,
        used="svd+lm" if refine_lm else "svd",
        field_norm=float(field_norm),
        coverage_pct=coverage,
        condition_number=condition,
        n_samples=int(m.shape[0]),
    )


def fit_ellipsoid(
    samples: np.ndarray,
    refine_lm: bool = True,
    field_norm: float = 1.0,
    min_coverage_pct: float = 20.0,
    max_condition: float = 100.0,
    extra_samples: dict[str, np.ndarray] | None = None,
    max_norm_mismatch: float = 0.01,
) -> EllipsoidFit:
    """Fit ``S'`` and ``o`` so that ``|S'(m - o)| = field_norm`` (step 1, eqs. 17-24).

    Parameters
    ----------
    samples : array_like, shape (n, 3)
        Raw magnetometer readings ``m`` (sensor frame), finite, n >= 10; rows without a fresh
        sample must be removed first (:func:`field_samples`).
    refine_lm : bool
        Refine the algebraic solution by Levenberg-Marquardt on eq. 17 and use the refinement.
    field_norm : float
        Norm of the calibrated field, > 0 (1 for a normalised magnetometer).
    min_coverage_pct : float
        Refuse data whose step-1-calibrated directions occupy fewer than this percentage of the
        cells of the equal-area sphere partition (:func:`sphere_coverage_pct`).
    max_condition : float
        Refuse data whose design-matrix condition number (see :class:`EllipsoidFit`) exceeds this.
    extra_samples : dict of str to array_like, shape (n_j, 3), optional
        Readings of other recordings in the same field (e.g. the cube's magnetometer samples),
        offered for more coverage. Each is first checked against the fit of ``samples``: it joins
        the fit only if the median of its step-1 norm differs from ``field_norm`` by at most
        ``max_norm_mismatch`` (relative), i.e. it was recorded in the same field; the decision and
        the mismatch are recorded in :attr:`EllipsoidFit.extra`.
    max_norm_mismatch : float
        Relative tolerance of that check (0.01 = 1 % of the field norm).

    Returns
    -------
    EllipsoidFit

    Raises
    ------
    ValueError
        If the samples are not finite or too few; if the fitted quadric is not an ellipsoid
        (``A`` not positive definite); if the coverage or the condition number is out of bounds;
        if the LM refinement does not converge. The message gives the coverage in % and the
        condition number.

    Notes
    -----
    The data are centred and scaled to unit RMS radius before ``D`` is built (the SVD is then
    invariant to the unit of the readings); ``d`` is mapped back before eqs. 21-22. ``d`` is fixed
    up to scale and sign: the sign is chosen so that ``Q`` (the quadratic part) is positive
    definite, and ``A = Q / (o^T Q o - d_10)`` gives ``(m - o)^T A (m - o) = 1``. Eq. 21 is the
    Cholesky factorisation ``A = S'^T S'`` with ``S'`` upper triangular, positive diagonal.

    References
    ----------
    Zhang, Hoeflinger, Reindl, "Calibration of an IMU Using 3-D Rotation Platform",
    IEEE Sensors J. 14(6), 2014, eqs. 17-24.
    """
    primary = _fit(samples, refine_lm, field_norm, min_coverage_pct, max_condition)
    extra: dict[str, dict] = {}
    accepted = []
    for name, values in (extra_samples or {}).items():
        v = np.asarray(values, dtype=float)
        if v.ndim != 2 or v.shape[1] != 3 or not np.isfinite(v).all() or v.shape[0] == 0:
            raise ValueError(
                f"extra magnetometer samples {name!r}: expected finite readings of shape (n, 3), "
                f"got shape {v.shape}"
            )
        norm = np.linalg.norm(primary.apply(v), axis=1)
        mismatch = float(np.median(norm) / field_norm - 1.0)
        ok = abs(mismatch) <= max_norm_mismatch
        extra[name] = {"n_samples": int(v.shape[0]), "norm_mismatch": mismatch, "used": ok}
        if ok:
            accepted.append(v)
    if not accepted:
        return EllipsoidFit(**{**primary.__dict__, "extra": extra})
    combined = _fit(
        np.vstack([np.asarray(samples, dtype=float), *accepted]),
        refine_lm,
        field_norm,
        min_coverage_pct,
        max_condition,
    )
    return EllipsoidFit(**{**combined.__dict__, "extra": extra})


@dataclass(frozen=True)
class MagnetometerCalibration:
    """Steps 1 and 2 together: the calibration and what produced it.

    Attributes
    ----------
    calibration : SensorCalibration
        ``matrix = T_R S'`` and ``o`` (eq. 16), with the covariance of its parameters (step 1's,
        the alignment's own and step 1's carried through the alignment, to first order;
        :mod:`imucal.fits.propagation`; None when fitted without).
    step1 : EllipsoidFit
    alignments : dict of str to AlignmentResult
        Step 2 by both methods, keys 'full' and 'paper'.
    method : str
        The step-2 method used for :attr:`calibration`.
    """

    calibration: SensorCalibration
    step1: EllipsoidFit
    alignments: dict = field(default_factory=dict)
    method: str = "full"

    def to_dict(self) -> dict:
        return {
            "calibration": self.calibration.to_dict(),
            "step1": self.step1.to_dict(),
            "step2": {
                "used": self.method,
                **{name: a.to_dict() for name, a in self.alignments.items()},
            },
        }


def calibrate_alignment(
    step1: EllipsoidFit,
    phases: dict[str, np.ndarray],
    method: str = "full",
    exact: bool = True,
    *,
    with_covariance: bool = True,
) -> MagnetometerCalibration:
    """Step 2 (eqs. 25-27): ``T_R,mag`` from the phases, by both methods; calibration by one.

    Parameters
    ----------
    step1 : EllipsoidFit
        Result of :func:`fit_ellipsoid`.
    phases : dict of str to array_like, shape (n_i, 3)
        Phase label ('x', 'y', 'z') -> raw magnetometer readings of that rotation3d phase.
    method : {'full', 'paper'}
        Step-2 method whose ``T_R`` goes into the calibration (both are computed and reported).
    exact : bool
        Exact rotation or the paper's small-angle matrix (eq. 5) for ``T_R``.
    with_covariance : bool
        Carry step 1's uncertainty through the alignment into the calibration's covariance and
        std (ten alignment refits, :func:`imucal.fits.propagation.alignment_sensitivity`), the
        alignments' own for residuals correlated in time; False leaves the calibration's unknown
        and gives the alignments the plain one (``correlated=False``), for callers that read
        the fitted values only.

    Returns
    -------
    MagnetometerCalibration

    Raises
    ------
    ValueError
        As :func:`imucal.fits.alignment.align_constant_component`.
    """
    step1_phases = {label: step1.apply(np.asarray(v, dtype=float)) for label, v in phases.items()}
    alignments = {
        name: align_constant_component(
            step1_phases, method=name, exact=exact, correlated=with_covariance
        )
        for name in ("full", "paper")
    }
    if method not in alignments:
        raise ValueError(f"unknown step-2 method {method!r}; expected one of {sorted(alignments)}")
    chosen = alignments[method]
    covariance = None
    if with_covariance:
        sensitivity = alignment_sensitivity(
            lambda ph: align_constant_component(ph, method=method, exact=exact, correlated=False),
            phases,
            step1.upper,
            step1.bias,
        )
        covariance = two_step_covariance(
            step1.upper,
            step1.bias,
            step1.selected.covariance,
            chosen.alpha_rad,
            chosen.covariance,
            sensitivity,
            exact,
        )
    calibration = SensorCalibration(
        sensor="mag",
        bias=step1.bias,
        matrix=chosen.matrix @ step1.upper,
        unit=SI_UNITS["mag"],
        std=std_of(covariance),
        covariance=covariance,
        quality={
            "ellipsoid": {"rule": "covariance scaled by the residuals (sigma^2 = r.r / dof)"},
            "alignment": {"rule": ALIGNMENT_RULE},
        },
        method=(
            f"step 1: ellipsoid {step1.used}; step 2: {method} "
            f"({'exact rotation' if exact else 'small-angle eq. 5'})"
        ),
    )
    return MagnetometerCalibration(calibration, step1, alignments, method)
