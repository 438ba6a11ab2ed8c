"""Accelerometer cube fit, step 1 of the accelerometer calibration (Zhang et al. 2014, eq. 32).

At rest the accelerometer reads the specific force, whose norm is gravity ``g`` in every
orientation. Eq. 32 fits the upper-triangular ``S'_acc = T_N S`` (6 parameters) and the bias
``o_acc`` (3) so that ``|S'(a - o)| = g`` over the static cube positions. The fit does not need to
know which position is which, hence at least 9 positions (the protocol uses 12: six faces down
and six at 45 degrees on a V-block; the 45-degree positions make the cross terms observable).
Step 2 (the rotation ``T_R,acc`` into frame B) is done in :mod:`imucal.fits.alignment`.

The magnitude model is shared with the gyroscope's magnitude-only rate-table fit
(:func:`imucal.fits.ratetable.fit_rate_table_magnitude`) through :func:`fit_magnitude_model`.

One fit, its input checks, its goodness of fit and its covariance (with the inflation rule)
belong together.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from imucal.uncertainty import goodness_of_fit, numerical_jacobian

#: Eq. 32 has 9 unknowns and one equation per position.
MIN_POSITIONS = 9
#: Positions of the cube protocol (6 faces, 6 on the V-block).
PROTOCOL_POSITIONS = 12
#: A position needs this many unsaturated samples (2 for its noise estimate; more for a mean).
MIN_SAMPLES_PER_POSITION = 10

# Index of the 6 upper-triangular entries of S' in the parameter vector (row-major).
_UPPER_INDEX = np.triu_indices(3)
_METHODS = ("means", "samples")


@dataclass(frozen=True)
class MagnitudeModelFit:
    """Result of a fit of ``|U (v - o)| = target`` (eqs. 32, 33 magnitude form).

    Attributes
    ----------
    upper : ndarray, shape (3, 3)
        Upper-triangular ``U = S'`` (positive diagonal).
    bias : ndarray, shape (3,)
        ``o``, in the unit of the vectors.
    covariance : ndarray, shape (9, 9)
        Covariance of ``(U[0,0], U[0,1], U[0,2], U[1,1], U[1,2], U[2,2], o_x, o_y, o_z)`` from the
        Jacobian at the solution, with the residuals weighted by their noise-predicted standard
        deviation (so it equals the Cramer-Rao bound to first order when the noise is right).
    singular_values : ndarray, shape (9,)
        Singular values of the weighted Jacobian at the solution, largest first; a ratio
        ``singular_values[-1] / singular_values[0]`` near zero means unobservable parameters.
    chi2 : float
        Sum of the squared weighted residuals (expected ``dof`` if the model and noise hold).
    dof : int
        Number of residuals minus 9.
    """

    upper: np.ndarray
    bias: np.ndarray
    covariance: np.ndarray
    singular_values: np.ndarray
    chi2: float
    dof: int

    @property
    def std_upper(self) -> np.ndarray:
        """Standard deviation of each entry of :attr:`upper`, shape (3, 3) (0 below the diagonal)."""
        out = np.zeros((3, 3))
        out[_UPPER_INDEX] = np.sqrt(np.diag(self.covariance)[:6])
        return out

    @property
    def std_bias(self) -> np.ndarray:
        """Standard deviation of :attr:`bias`, shape (3,)."""
        return np.sqrt(np.diag(self.covariance)[6:])


def _unpack(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    upper = np.zeros((3, 3))
    upper[_UPPER_INDEX] = theta[:6]
    return upper, theta[6:]


def _pack(upper: np.ndarray, bias: np.ndarray) -> np.ndarray:
    return np.concatenate([np.asarray(upper)[_UPPER_INDEX], np.asarray(bias)])


def _residual_std(
    upper: np.ndarray, bias: np.ndarray, vectors: np.ndarray, counts: np.ndarray, noise: np.ndarray
) -> np.ndarray:
    """Noise std of ``|U(v - o)|`` per vector: ``|diag(noise) U^T n| / sqrt(count)``, shape (n,)."""
    scaled = (vectors - bias) @ upper.T
    direction = scaled / np.linalg.norm(scaled, axis=1, keepdims=True)
    # first-order propagation of white noise (std per axis) through the norm
    return np.linalg.norm((direction @ upper) * noise, axis=1) / np.sqrt(counts)


def fit_magnitude_model(
    vectors: np.ndarray,
    target_norms: np.ndarray,
    counts: np.ndarray,
    noise_std: np.ndarray,
    initial_upper: np.ndarray,
    initial_bias: np.ndarray,
) -> MagnitudeModelFit:
    """Levenberg-Marquardt fit of ``|U (v - o)| = target`` with U upper triangular (eq. 32).

    Every residual ``|U(v_j - o)| - target_j`` is divided by its noise standard deviation,
    predicted to first order from ``noise_std`` and ``counts`` (a vector that is the mean of
    ``counts[j]`` samples has ``1/sqrt(counts[j])`` of the sample noise). The weights are computed
    at the initial guess, the fit is solved, and the weights are recomputed once at that solution
    and the fit repeated (so they no longer depend on the initial guess).

    Parameters
    ----------
    vectors : ndarray, shape (n, 3)
        Readings (or means of readings), SI unit of the sensor.
    target_norms : ndarray, shape (n,)
        Norm each calibrated vector must have (``g`` for the cube, ``|rate|`` for a rate table).
    counts : ndarray, shape (n,)
        Number of samples behind each vector (1 for single samples).
    noise_std : ndarray, shape (3,)
        White-noise standard deviation of one sample per axis, unit of the vectors.
    initial_upper : ndarray, shape (3, 3)
        Starting ``U`` (upper triangular).
    initial_bias : ndarray, shape (3,)
        Starting ``o``.

    Returns
    -------
    MagnitudeModelFit

    Raises
    ------
    ValueError
        If fewer than 9 vectors are given, or the noise is not positive and finite.
    """
    v = np.asarray(vectors, dtype=float)
    target = np.asarray(target_norms, dtype=float)
    n_vec = np.asarray(counts, dtype=float)
    noise = np.asarray(noise_std, dtype=float).reshape(3)
    if v.ndim != 2 or v.shape[1] != 3 or len(v) < 9:
        raise ValueError(f"need at least 9 vectors of shape (n, 3), got shape {v.shape}")
    if not np.all(np.isfinite(noise)) or np.any(noise <= 0):
        raise ValueError(f"noise_std must be 3 positive finite numbers, got {noise.tolist()}")

    def residuals(theta: np.ndarray, weight: np.ndarray) -> np.ndarray:
        upper, bias = _unpack(theta)
        return weight * (np.linalg.norm((v - bias) @ upper.T, axis=1) - target)

    def jacobian(theta: np.ndarray, weight: np.ndarray) -> np.ndarray:
        upper, bias = _unpack(theta)
        centred = v - bias
        scaled = centred @ upper.T
        direction = scaled / np.linalg.norm(scaled, axis=1, keepdims=True)
        # d|U c| / dU_kl = n_k c_l ;  d|U c| / do = -U^T n
        d_upper = direction[:, _UPPER_INDEX[0]] * centred[:, _UPPER_INDEX[1]]
        d_bias = -direction @ upper
        return weight[:, None] * np.hstack([d_upper, d_bias])

    theta = _pack(initial_upper, initial_bias)
    for _ in range(2):
        upper, bias = _unpack(theta)
        weight = 1.0 / _residual_std(upper, bias, v, n_vec, noise)
        sol = least_squares(residuals, theta, jac=jacobian, method="lm", args=(weight,))
        theta = sol.x
    upper, bias = _unpack(theta)
    if np.any(np.diag(upper) < 0):
        # |U c| is invariant under sign flips of U's rows; keep the positive-diagonal solution
        upper = np.sign(np.diag(upper))[:, None] * upper
        theta = _pack(upper, bias)
    jac = jacobian(theta, weight)
    singular_values = np.linalg.svd(jac, compute_uv=False)
    covariance = np.linalg.pinv(jac.T @ jac)
    chi2 = float(np.sum(residuals(theta, weight) ** 2))
    return MagnitudeModelFit(upper, bias, covariance, singular_values, chi2, len(v) - 9)


@dataclass(frozen=True)
class CubeFit:
    """Result of the cube fit (eq. 32).

    Attributes
    ----------
    upper : ndarray, shape (3, 3)
        ``S'_acc`` (upper triangular, positive diagonal, dimensionless).
    bias : ndarray, shape (3,)
        ``o_acc``, m/s^2.
    std_upper : ndarray, shape (3, 3)
        Standard deviation of the entries of ``upper`` (0 below the diagonal).
    std_bias : ndarray, shape (3,)
        Standard deviation of ``bias``, m/s^2.
    covariance : ndarray, shape (9, 9)
        Covariance of ``(S'00, S'01, S'02, S'11, S'12, S'22, o_x, o_y, o_z)``.
    labels : tuple of str
        Label of each position used.
    position_means : ndarray, shape (n_pos, 3)
        Mean reading of each position used (unsaturated samples), m/s^2.
    n_samples : ndarray of int, shape (n_pos,)
        Samples used per position.
    n_excluded : ndarray of int, shape (n_pos,)
        Saturated samples excluded per position.
    magnitude_error_before_m_s2 : ndarray, shape (n_pos,)
        ``|mean reading| - g`` (uncalibrated), the paper's Fig. 10 "before".
    magnitude_error_after_m_s2 : ndarray, shape (n_pos,)
        ``|S'(mean - o)| - g``, Fig. 10 "after".
    noise_std_m_s2 : ndarray, shape (3,)
        Sample noise per axis used for the weights (pooled within-position scatter unless given).
    chi2 : float
        Sum of squared noise-weighted residuals; about ``dof`` when the data fit the model.
    dof : int
        Residuals minus 9.
    method : str
        'means' or 'samples' (see :func:`fit_cube`).
    warnings : tuple of str
        Data problems the fit worked around (saturated samples, dropped positions).
    """

    upper: np.ndarray
    bias: np.ndarray
    std_upper: np.ndarray
    std_bias: np.ndarray
    covariance: np.ndarray
    labels: tuple[str, ...]
    position_means: np.ndarray
    n_samples: np.ndarray
    n_excluded: np.ndarray
    magnitude_error_before_m_s2: np.ndarray
    magnitude_error_after_m_s2: np.ndarray
    noise_std_m_s2: np.ndarray
    chi2: float
    dof: int
    method: str
    warnings: tuple[str, ...]


def _saturation_masks(
    positions: list[np.ndarray],
    labels: Sequence[str],
    saturated: Sequence[np.ndarray] | None,
    limit_m_s2: float | None,
) -> list[np.ndarray]:
    masks = [np.zeros(len(p), dtype=bool) for p in positions]
    if saturated is not None:
        if len(saturated) != len(positions):
            raise ValueError(
                f"saturated has {len(saturated)} masks for {len(positions)} positions; "
                "expected one boolean mask per position"
            )
        for i, (m, p, label) in enumerate(zip(saturated, positions, labels)):
            m = np.asarray(m, dtype=bool)
            if m.ndim == 2:
                m = m.any(axis=1)
            if m.shape != (len(p),):
                raise ValueError(
                    f"position {label!r}: saturation mask has shape {np.shape(saturated[i])}, "
                    f"expected ({len(p)},) or ({len(p)}, 3)"
                )
            masks[i] |= m
    if limit_m_s2 is not None:
        if not np.isfinite(limit_m_s2) or limit_m_s2 <= 0:
            raise ValueError(f"saturation limit must be positive, got {limit_m_s2!r} m/s^2")
        # a reading at the range limit (to rounding of counts * sensitivity) is clipped
        for i, p in enumerate(positions):
            masks[i] |= np.any(np.abs(p) >= limit_m_s2 * (1 - 1e-9), axis=1)
    return masks


def _pooled_noise_std(positions: list[np.ndarray]) -> np.ndarray:
    """Pooled within-position standard deviation per axis, shape (3,)."""
    ss = sum(((p - p.mean(axis=0)) ** 2).sum(axis=0) for p in positions)
    dof = sum(len(p) - 1 for p in positions)
    return np.sqrt(ss / dof)


def _initial_guess(means: np.ndarray, gravity_m_s2: float) -> tuple[np.ndarray, np.ndarray]:
    """Algebraic ellipsoid ``x^T A x + b^T x = 1`` (9 unknowns, linear) as the LM start."""
    x, y, z = means.T
    design = np.column_stack([x * x, y * y, z * z, 2 * x * y, 2 * x * z, 2 * y * z, x, y, z])
    p, *_ = np.linalg.lstsq(design, np.ones(len(means)), rcond=None)
    a = np.array([[p[0], p[3], p[4]], [p[3], p[1], p[5]], [p[4], p[5], p[2]]])
    try:
        centre = -0.5 * np.linalg.solve(a, p[6:])
        shape = a / (1.0 + centre @ a @ centre) * gravity_m_s2**2
        upper = np.linalg.cholesky(shape).T  # shape = U^T U
        return upper, centre
    except np.linalg.LinAlgError:
        # not an ellipsoid (poor coverage or outliers): start from a unit sphere scaled to g
        scale = gravity_m_s2 / np.median(np.linalg.norm(means, axis=1))
        return scale * np.eye(3), np.zeros(3)


def fit_cube(
    positions: Sequence[np.ndarray],
    gravity_m_s2: float,
    *,
    labels: Sequence[str] | None = None,
    saturated: Sequence[np.ndarray] | None = None,
    saturation_limit_m_s2: float | None = None,
    noise_std_m_s2: np.ndarray | None = None,
    method: str = "means",
) -> CubeFit:
    """Fit ``S'_acc`` and ``o_acc`` to the static cube positions (eq. 32).

    Parameters
    ----------
    positions : sequence of ndarray, each shape (n_i, 3)
        Accelerometer readings (m/s^2, sensor frame) of each static position.
    gravity_m_s2 : float
        Local gravity ``g``, m/s^2.
    labels : sequence of str, optional
        Name of each position (default ``p01``, ``p02``, ...), used in messages.
    saturated : sequence of ndarray of bool, each shape (n_i,) or (n_i, 3), optional
        True where a sample (or one of its axes) is saturated.
    saturation_limit_m_s2 : float, optional
        Sensor range ``range_counts * sensitivity``; a sample with any ``|value| >=`` this is
        saturated. Both this and ``saturated`` may be given.
    noise_std_m_s2 : ndarray, shape (3,), optional
        Sample noise per axis; default: pooled within-position standard deviation.
    method : {'means', 'samples'}
        'means' (default): one residual per position, its mean weighted by its sample count.
        'samples': one residual per sample, eq. 32 as printed.

    Returns
    -------
    CubeFit

    Raises
    ------
    ValueError
        If fewer than 9 positions remain after excluding saturated samples (positions with fewer
        than 10 unsaturated samples are dropped), if a position holds non-finite values, or if
        the positions do not constrain the 9 parameters.

    Notes
    -----
    Why position means by default: for white Gaussian noise the mean of a static position is a
    sufficient statistic for its constant vector, so fitting the means with weights
    ``n_i / var_i`` loses no information and is ``n`` times cheaper. It is also less biased: a
    single sample's norm ``|a + e|`` exceeds ``|a|`` on average by ``sigma_perp^2 / (2 g)``
    (``sigma_perp^2`` the noise variance across the gravity direction, ``2 sigma^2`` for
    isotropic noise), while the norm of a mean of ``n`` samples is biased ``n`` times less. At
    sigma = 0.02 m/s^2 the per-sample bias is 4e-5 m/s^2 (relative 4e-6, a tenth of the scale's
    Cramer-Rao std of 5e-5 for 12 positions of 600 samples, see docs/accuracy-inertial.md); with
    means it is 7e-8 m/s^2.

    Each residual is weighted by its noise standard deviation propagated through the norm
    (:func:`fit_magnitude_model`), so the covariance from the Jacobian is the Cramer-Rao bound
    (:func:`cube_crlb`) to first order. The standard deviations assume white noise; compare
    ``chi2`` with ``dof`` to see whether the positions scatter more than the noise explains
    (a position not at rest, a tilted V-block).

    References
    ----------
    Zhang, Hoeflinger, Reindl, IEEE Sensors J. 14(6), 2014, eq. 32 and Fig. 10.
    """
    if method not in _METHODS:
        raise ValueError(f"method must be one of {_METHODS}, got {method!r}")
    if not np.isfinite(gravity_m_s2) or gravity_m_s2 <= 0:
        raise ValueError(f"gravity_m_s2 must be positive, got {gravity_m_s2!r}")
    arrays = [np.asarray(p, dtype=float) for p in positions]
    labels = (
        tuple(labels) if labels is not None else tuple(f"p{i + 1:02d}" for i in range(len(arrays)))
    )
    if len(labels) != len(arrays):
        raise ValueError(f"{len(labels)} labels for {len(arrays)} positions; expected one each")
    for p, label in zip(arrays, labels):
        if p.ndim != 2 or p.shape[1] != 3:
            raise ValueError(f"position {label!r}: expected shape (n, 3), got {p.shape}")
        bad = int(np.sum(~np.isfinite(p).all(axis=1)))
        if bad:
            raise ValueError(
                f"position {label!r}: {bad} of {len(p)} accelerometer samples are not finite; "
                "expected finite m/s^2 on every row"
            )
    masks = _saturation_masks(arrays, labels, saturated, saturation_limit_m_s2)

    warnings: list[str] = []
    kept, kept_labels, excluded = [], [], []
    for p, mask, label in zip(arrays, masks, labels):
        n_sat = int(mask.sum())
        if len(p) - n_sat < MIN_SAMPLES_PER_POSITION:
            warnings.append(
                f"position {label!r} dropped: {len(p) - n_sat} of {len(p)} samples unsaturated, "
                f"need {MIN_SAMPLES_PER_POSITION}"
            )
            continue
        if n_sat:
            warnings.append(
                f"position {label!r}: {n_sat} of {len(p)} saturated samples excluded "
                "(the mean of the rest is biased towards zero on the clipped axis)"
            )
        kept.append(p[~mask])
        kept_labels.append(label)
        excluded.append(n_sat)
    if len(kept) < MIN_POSITIONS:
        raise ValueError(
            f"cube fit needs at least {MIN_POSITIONS} static positions (eq. 32 has 9 unknowns; "
            f"the protocol uses {PROTOCOL_POSITIONS}), found {len(kept)} usable of {len(arrays)}"
            + (f": {'; '.join(warnings)}" if warnings else "")
        )

    means = np.array([p.mean(axis=0) for p in kept])
    counts = np.array([len(p) for p in kept])
    if noise_std_m_s2 is None:
        noise = _pooled_noise_std(kept)
    else:
        noise = np.asarray(noise_std_m_s2, dtype=float).reshape(3)
    if np.any(noise <= 0):
        raise ValueError(
            f"accelerometer noise per axis is {noise.tolist()} m/s^2; expected > 0 "
            "(constant readings: pass noise_std_m_s2, e.g. the quantisation step / sqrt(12))"
        )

    upper0, bias0 = _initial_guess(means, gravity_m_s2)
    if method == "means":
        fit = fit_magnitude_model(
            means, np.full(len(means), gravity_m_s2), counts, noise, upper0, bias0
        )
    else:
        samples = np.vstack(kept)
        fit = fit_magnitude_model(
            samples,
            np.full(len(samples), gravity_m_s2),
            np.ones(len(samples)),
            noise,
            upper0,
            bias0,
        )
    sv = fit.singular_values
    if sv[-1] <= 1e-10 * sv[0]:
        raise ValueError(
            f"the {len(kept)} cube positions do not constrain S' and o (Jacobian singular values "
            f"{sv[-1]:.3g} vs {sv[0]:.3g}); expected positions spread over all directions, "
            "including the 45-degree V-block positions"
        )
    before = np.linalg.norm(means, axis=1) - gravity_m_s2
    after = np.linalg.norm((means - fit.bias) @ fit.upper.T, axis=1) - gravity_m_s2
    return CubeFit(
        upper=fit.upper,
        bias=fit.bias,
        std_upper=fit.std_upper,
        std_bias=fit.std_bias,
        covariance=fit.covariance,
        labels=tuple(kept_labels),
        position_means=means,
        n_samples=counts,
        n_excluded=np.array(excluded),
        magnitude_error_before_m_s2=before,
        magnitude_error_after_m_s2=after,
        noise_std_m_s2=noise,
        chi2=fit.chi2,
        dof=fit.dof,
        method=method,
        warnings=tuple(warnings),
    )


@dataclass(frozen=True)
class HeldOut:
    """Leave-one-position-out ``|a| - g`` of the cube fit, and what its covariance predicts.

    Attributes
    ----------
    before : ndarray, shape (n_pos,)
        ``|mean_i| - g`` of the raw readings, m/s^2.
    after : ndarray, shape (n_pos,)
        ``|S'_(-i) (mean_i - o_(-i))| - g`` with ``S'_(-i), o_(-i)`` fitted (eq. 32) on all
        positions but ``i``, m/s^2; NaN where that fit fails (the others do not constrain it).
    predicted_std : ndarray, shape (n_pos,)
        The standard deviation of ``after`` that the held-out fit's reported covariance and the
        noise of ``mean_i`` predict, both inflated by the held-out fit's goodness of fit
        (:func:`imucal.uncertainty.goodness_of_fit`: positions that scatter beyond their noise
        do so held out too), m/s^2; NaN where the fit fails.
    """

    before: np.ndarray
    after: np.ndarray
    predicted_std: np.ndarray

    @property
    def z(self) -> np.ndarray:
        """``after / predicted_std``: about unit spread when the covariance is honest."""
        return self.after / self.predicted_std


def heldout_errors(
    positions: Sequence[np.ndarray], gravity_m_s2: float, *, method: str = "means"
) -> HeldOut:
    """Leave-one-position-out ``|a| - g``: each position against the fit on the others.

    Parameters
    ----------
    positions : sequence of ndarray, each shape (n_i, 3)
        Accelerometer readings of each static position, m/s^2 (finite, unsaturated).
    gravity_m_s2 : float
        Local gravity ``g``, m/s^2.
    method : {'means', 'samples'}
        Passed to :func:`fit_cube`.

    Returns
    -------
    HeldOut

    Raises
    ------
    ValueError
        If there are fewer than ``MIN_POSITIONS + 1`` positions (each fit needs 9).

    Notes
    -----
    The in-sample errors of :func:`fit_cube` shrink with the 9 fitted parameters (to zero for 9
    positions); a held-out position shows how the calibration does on a pose it did not see, and
    its spread against ``predicted_std`` whether the reported covariance is honest there.
    """
    arrays = [np.asarray(p, dtype=float) for p in positions]
    if len(arrays) < MIN_POSITIONS + 1:
        raise ValueError(
            f"{len(arrays)} positions: leaving one out needs at least {MIN_POSITIONS + 1} "
            f"(the fit has {MIN_POSITIONS} unknowns)"
        )
    means = np.array([p.mean(axis=0) for p in arrays])
    after = np.full(len(arrays), np.nan)
    predicted = np.full(len(arrays), np.nan)
    for i in range(len(arrays)):
        try:
            fit = fit_cube(arrays[:i] + arrays[i + 1 :], gravity_m_s2, method=method)
        except ValueError:  # the others alone do not constrain S' and o
            continue

        def magnitude(theta: np.ndarray, mean: np.ndarray = means[i]) -> np.ndarray:
            upper, bias = _unpack(theta)
            return np.array([np.linalg.norm(upper @ (mean - bias))])

        theta = _pack(fit.upper, fit.bias)
        after[i] = magnitude(theta)[0] - gravity_m_s2
        inflation = goodness_of_fit(fit.chi2, fit.dof).inflation if fit.dof >= 1 else 1.0
        jac = numerical_jacobian(magnitude, theta)
        direction = fit.upper @ (means[i] - fit.bias)
        direction /= np.linalg.norm(direction)
        gain = fit.upper.T @ direction  # d|S'(m - o)| / dm
        noise = np.cov(arrays[i].T) / len(arrays[i]) if len(arrays[i]) > 1 else np.zeros((3, 3))
        # positions that scatter beyond their noise (the inflation) do so held out as well
        variance = inflation * ((jac @ fit.covariance @ jac.T)[0, 0] + gain @ noise @ gain)
        predicted[i] = np.sqrt(variance)
    return HeldOut(np.linalg.norm(means, axis=1) - gravity_m_s2, after, predicted)


def cube_crlb(
    upper: np.ndarray,
    directions: np.ndarray,
    n_samples: np.ndarray,
    noise_std_m_s2: np.ndarray,
    gravity_m_s2: float,
) -> np.ndarray:
    """Cramer-Rao bound of ``(S' upper entries, o)`` for the cube problem at a known truth.

    Model: the samples of position ``j`` are ``S'^-1 g d_j + o + e`` with ``e`` white Gaussian,
    std ``noise_std_m_s2`` per axis, and an unknown unit vector ``d_j`` (2 nuisance parameters per
    position: the fit does not know the orientations). The bound is the (S', o) block of the
    inverse Fisher information of all ``9 + 2 n`` parameters (the nuisances are not assumed known).

    Parameters
    ----------
    upper : ndarray, shape (3, 3)
        True ``S'``.
    directions : ndarray, shape (n, 3)
        Unit gravity direction of each position in the frame of ``S' (a - o)``.
    n_samples : ndarray, shape (n,)
        Samples per position.
    noise_std_m_s2 : ndarray, shape (3,)
        Sample noise per axis, m/s^2.
    gravity_m_s2 : float

    Returns
    -------
    ndarray, shape (9, 9)
        Lower bound on the covariance of ``(S'00, S'01, S'02, S'11, S'12, S'22, o_x, o_y, o_z)``.
    """
    u = np.asarray(upper, dtype=float)
    d = np.asarray(directions, dtype=float)
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    counts = np.asarray(n_samples, dtype=float)
    info_weight = 1.0 / np.asarray(noise_std_m_s2, dtype=float).reshape(3) ** 2
    u_inv = np.linalg.inv(u)
    n_pos = len(d)
    fisher = np.zeros((9 + 2 * n_pos, 9 + 2 * n_pos))
    for j in range(n_pos):
        jac = np.zeros((3, 9 + 2 * n_pos))
        x = u_inv @ (gravity_m_s2 * d[j])
        # d(U^-1 g d)/dU_km = -U^-1 E_km U^-1 g d = -U^-1[:, k] x_m
        for col, (k, m) in enumerate(zip(*_UPPER_INDEX)):
            jac[:, col] = -u_inv[:, k] * x[m]
        jac[:, 6:9] = np.eye(3)
        # two tangent directions of d_j on the unit sphere
        tangent = np.linalg.svd(d[j][None, :])[2][1:]
        jac[:, 9 + 2 * j : 11 + 2 * j] = u_inv @ (gravity_m_s2 * tangent.T)
        fisher += counts[j] * jac.T @ (info_weight[:, None] * jac)
    return np.linalg.inv(fisher)[:9, :9]
