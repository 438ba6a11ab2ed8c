"""Covariance of a sensor's calibration parameters: the delta method and the goodness of fit.

A sensor's calibration is ``calibrated = matrix @ (reading - bias)`` (eq. 11). Its parameter
vector, in the order of :data:`PARAMETERS`, is the bias (3), the matrix entries row by row (9)
and the derived scale, non-orthogonality xi and rotation alpha of ``matrix`` (3 each, eqs. 2-10,
:func:`imucal.errormodel.decompose`): 21 entries, of which the last 9 are functions of the
matrix, so the 21 x 21 covariance has rank 12 at most.

Covariances are carried from the fits to the calibration by the delta method: a function
``y = f(x)`` of parameters with covariance ``C`` gets ``J C J^T`` with ``J = df/dx`` at the
estimate, by central differences (:func:`numerical_jacobian`). This is first order: it holds
while the standard deviations are small against the curvature of ``f``, which for calibration
parameters (scales near 1, angles of a few degrees, relative errors of 1e-4) they are.

Goodness of fit: a fit whose covariance assumes white noise of a known level (the cube fit, the
rate table, the gyroscope bias) reports ``chi2`` with ``dof`` degrees of freedom. When ``chi2``
exceeds the :data:`INFLATION_QUANTILE` quantile of the chi-square distribution, the data scatter
more than the noise explains (drift, disturbed positions, a model that does not fit) and the
covariance is multiplied by ``chi2 / dof`` (Birge's ratio, the rule of the Particle Data Group's
scale factor). Below that quantile the covariance is kept: a small excess is what noise gives.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import special

from imucal import errormodel
from imucal.columns import AXES

#: Names of the calibration parameters, in the order of the covariance (units as in the
#: calibration: bias in the sensor's unit, matrix, scale dimensionless, angles rad).
PARAMETERS: tuple[str, ...] = (
    *(f"bias_{a}" for a in AXES),
    *(f"matrix_{r}{c}" for r in AXES for c in AXES),
    *(f"scale_{a}" for a in AXES),
    *(f"xi_{a}_rad" for a in AXES),
    *(f"alpha_{a}_rad" for a in AXES),
)
#: Where each group of :data:`PARAMETERS` sits (the keys of ``SensorCalibration.std``).
GROUPS = {
    "bias": slice(0, 3),
    "matrix": slice(3, 12),
    "scale": slice(12, 15),
    "xi_rad": slice(15, 18),
    "alpha_rad": slice(18, 21),
}
#: A fit is inflated when its chi-square exceeds this quantile of its chi-square distribution.
INFLATION_QUANTILE = 0.999


def numerical_jacobian(
    func: Callable[[np.ndarray], np.ndarray], x: np.ndarray, rel_step: float = 1e-6
) -> np.ndarray:
    """``d func / d x`` by central differences, shape (m, n).

    Parameters
    ----------
    func : callable
        Maps an array of shape (n,) to an array of shape (m,).
    x : ndarray, shape (n,)
        Where to differentiate.
    rel_step : float
        Step of entry i: ``rel_step * max(1, |x_i|)``.
    """
    x = np.asarray(x, dtype=float)
    columns = []
    for i in range(x.size):
        h = rel_step * max(1.0, abs(x[i]))
        step = np.zeros_like(x)
        step[i] = h
        plus = np.asarray(func(x + step), dtype=float)
        minus = np.asarray(func(x - step), dtype=float)
        columns.append((plus - minus) / (2 * h))
    return np.column_stack(columns)


def propagate(
    func: Callable[[np.ndarray], np.ndarray], x: np.ndarray, covariance: np.ndarray
) -> np.ndarray:
    """Covariance of ``func(x)`` given that of ``x`` (delta method), shape (m, m)."""
    jac = numerical_jacobian(func, x)
    out = jac @ np.asarray(covariance, dtype=float) @ jac.T
    return (out + out.T) / 2


def _with_decomposition(bias_matrix: np.ndarray) -> np.ndarray:
    d = errormodel.decompose(bias_matrix[3:].reshape(3, 3))
    return np.concatenate([bias_matrix, d.scale, d.xi_rad, d.alpha_rad])


def calibration_covariance(
    bias: np.ndarray, matrix: np.ndarray, covariance: np.ndarray
) -> np.ndarray:
    """The 21 x 21 covariance of :data:`PARAMETERS` from that of (bias, matrix row-major).

    Parameters
    ----------
    bias : ndarray, shape (3,)
    matrix : ndarray, shape (3, 3)
    covariance : ndarray, shape (12, 12)
        Covariance of ``(bias, matrix.ravel())``.

    Returns
    -------
    ndarray, shape (21, 21)
    """
    x = np.concatenate([np.asarray(bias, dtype=float), np.asarray(matrix, dtype=float).ravel()])
    c = np.asarray(covariance, dtype=float)
    if c.shape != (12, 12) or not np.all(np.isfinite(c)):
        raise ValueError(f"expected a finite (12, 12) covariance, got shape {c.shape}")
    return propagate(_with_decomposition, x, c)


def std_of(covariance: np.ndarray | None) -> dict[str, np.ndarray]:
    """Standard deviation of each group of :data:`PARAMETERS` (matrix as 3 x 3); none when the
    covariance is unknown (None)."""
    if covariance is None:
        return {}
    std = np.sqrt(np.clip(np.diag(np.asarray(covariance, dtype=float)), 0.0, None))
    out = {name: std[s] for name, s in GROUPS.items()}
    out["matrix"] = out["matrix"].reshape(3, 3)
    return out


def upper_entries(upper: np.ndarray) -> np.ndarray:
    """The 6 entries of an upper-triangular matrix, row by row (the fits' parameter order)."""
    return np.asarray(upper, dtype=float)[np.triu_indices(3)]


def upper_matrix(entries: np.ndarray) -> np.ndarray:
    """Inverse of :func:`upper_entries`, shape (3, 3)."""
    out = np.zeros((3, 3))
    out[np.triu_indices(3)] = entries
    return out


def two_step_covariance(
    upper: np.ndarray,
    bias: np.ndarray,
    step1_covariance: np.ndarray,
    alpha_rad: np.ndarray,
    alpha_covariance: np.ndarray,
    sensitivity: np.ndarray,
    exact: bool = True,
) -> np.ndarray:
    """Covariance of a two-step calibration ``bias = o``, ``matrix = T_R(alpha) S'`` (eq. 16).

    Step 1 estimates ``theta = (S' upper entries (6), o (3))`` with ``step1_covariance``; step 2
    fits ``alpha`` on other data through step 1's output, so ``alpha`` carries its own noise
    (``alpha_covariance``, independent of step 1's) and step 1's error through
    ``sensitivity = d alpha / d theta``. Jointly::

        C = [[C1,      C1 G^T           ],
             [G C1,    C_alpha + G C1 G^T]]

    and the calibration follows by the delta method.

    Parameters
    ----------
    upper : ndarray, shape (3, 3)
    bias : ndarray, shape (3,)
    step1_covariance : ndarray, shape (9, 9)
        Of ``(upper entries row by row, bias)``.
    alpha_rad : ndarray, shape (3,)
    alpha_covariance : ndarray, shape (3, 3)
        Of ``alpha`` from step 2's own data.
    sensitivity : ndarray, shape (3, 9)
        ``d alpha / d theta``.
    exact : bool
        Exact rotation or the small-angle matrix of eq. 5.

    Returns
    -------
    ndarray, shape (21, 21)
        Covariance of :data:`PARAMETERS`.
    """
    c1 = np.asarray(step1_covariance, dtype=float)
    g = np.asarray(sensitivity, dtype=float)
    joint = np.zeros((12, 12))
    joint[:9, :9] = c1
    joint[9:, :9] = g @ c1
    joint[:9, 9:] = (g @ c1).T
    joint[9:, 9:] = np.asarray(alpha_covariance, dtype=float) + g @ c1 @ g.T
    theta = np.concatenate([upper_entries(upper), np.asarray(bias, dtype=float), alpha_rad])

    def calibration(p: np.ndarray) -> np.ndarray:
        matrix = errormodel.rotation_matrix(p[9:], exact) @ upper_matrix(p[:6])
        return np.concatenate([p[6:9], matrix.ravel()])

    cov12 = propagate(calibration, theta, joint)
    m = errormodel.rotation_matrix(alpha_rad, exact) @ np.asarray(upper, dtype=float)
    return calibration_covariance(bias, m, cov12)


def bias_matrix_covariance(
    bias: np.ndarray, matrix: np.ndarray, matrix_bias: np.ndarray | None = None
) -> np.ndarray:
    """The joint covariance (12, 12) of ``(bias, matrix row by row)`` from its blocks.

    Parameters
    ----------
    bias : ndarray, shape (3, 3)
        Covariance of the bias.
    matrix : ndarray, shape (9, 9)
        Covariance of the matrix entries.
    matrix_bias : ndarray, shape (9, 3), optional
        Cross-covariance of the matrix entries with the bias (zero when omitted).
    """
    out = np.zeros((12, 12))
    out[:3, :3] = np.asarray(bias, dtype=float)
    out[3:, 3:] = np.asarray(matrix, dtype=float)
    if matrix_bias is not None:
        out[3:, :3] = np.asarray(matrix_bias, dtype=float)
        out[:3, 3:] = out[3:, :3].T
    return out


def step1_only_covariance(
    upper: np.ndarray, bias: np.ndarray, covariance: np.ndarray
) -> np.ndarray:
    """Covariance (21, 21) of a calibration ``matrix = S'`` (no ``T_R``) from that of
    ``(S' upper entries, o)`` (9, 9): :func:`two_step_covariance` without a step 2."""
    return two_step_covariance(
        np.asarray(upper, dtype=float),
        np.asarray(bias, dtype=float),
        np.asarray(covariance, dtype=float),
        np.zeros(3),
        np.zeros((3, 3)),
        np.zeros((3, 9)),
    )


@dataclass(frozen=True)
class GoodnessOfFit:
    """Chi-square of a fit against its white-noise model and the inflation it implies.

    Attributes
    ----------
    chi2 : float
        Sum of squared noise-weighted residuals.
    dof : int
        Degrees of freedom.
    p_value : float
        Probability of a chi-square at least this large under the white-noise model.
    inflation : float
        Factor applied to the fit's covariance: ``chi2 / dof`` when ``chi2`` exceeds the
        :data:`INFLATION_QUANTILE` quantile, else 1.
    """

    chi2: float
    dof: int
    p_value: float
    inflation: float

    @property
    def ratio(self) -> float:
        """``chi2 / dof``."""
        return self.chi2 / self.dof

    def to_dict(self) -> dict:
        return {
            "chi2": self.chi2,
            "dof": self.dof,
            "chi2_per_dof": self.ratio,
            "p_value": self.p_value,
            "inflation": self.inflation,
            "rule": (
                f"covariance x chi2/dof when chi2 > the {INFLATION_QUANTILE:g} quantile of "
                "chi-square(dof)"
            ),
        }


def goodness_of_fit(chi2: float, dof: int) -> GoodnessOfFit:
    """Test ``chi2`` against the chi-square distribution with ``dof`` degrees of freedom.

    Raises
    ------
    ValueError
        If ``dof`` < 1 or ``chi2`` is negative or not finite.
    """
    if dof < 1:
        raise ValueError(f"goodness of fit needs dof >= 1, got {dof}")
    if not np.isfinite(chi2) or chi2 < 0:
        raise ValueError(f"chi2 must be finite and >= 0, got {chi2!r}")
    # chi-square quantile and survival function (scipy.special's, lighter to import than stats)
    limit = special.chdtri(dof, 1.0 - INFLATION_QUANTILE)
    inflation = float(chi2 / dof) if chi2 > limit else 1.0
    return GoodnessOfFit(float(chi2), int(dof), float(special.chdtrc(dof, chi2)), inflation)


def calibrated_covariance(
    matrix: np.ndarray, bias: np.ndarray, covariance: np.ndarray, readings: np.ndarray
) -> np.ndarray:
    """Covariance of calibrated values from the parameters' covariance, per sample.

    ``c = matrix (r - bias)``: ``dc = d(matrix) (r - bias) - matrix d(bias)``, so
    ``J = [-matrix, I_3 kron (r - bias)^T]`` and ``Cov(c) = J C J^T``. The reading's own noise
    is not included (it is the sensor's, not the calibration's).

    Parameters
    ----------
    matrix : ndarray, shape (3, 3)
    bias : ndarray, shape (3,)
    covariance : ndarray, shape (12, 12) or (21, 21)
        Of ``(bias, matrix row by row)`` (the first 12 of :data:`PARAMETERS` are used).
    readings : ndarray, shape (n, 3)
        In the calibration's input unit.

    Returns
    -------
    ndarray, shape (n, 3, 3)
        In the output unit squared.
    """
    m = np.asarray(matrix, dtype=float)
    centred = np.asarray(readings, dtype=float) - np.asarray(bias, dtype=float)
    c = np.asarray(covariance, dtype=float)[:12, :12]
    n = len(centred)
    jac = np.zeros((n, 3, 12))
    jac[:, :, :3] = -m
    for i in range(3):
        jac[:, i, 3 + 3 * i : 6 + 3 * i] = centred
    return np.einsum("nip,pq,njq->nij", jac, c, jac)
