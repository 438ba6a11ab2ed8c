"""Held-out comparisons whose residuals are correlated over hours: long blocks as clusters.

A static pose's residual drifts with the part (bias wander, the pose's own thermal history), so
its samples are far from independent; blocks of a length beyond that correlation are nearly
so. Here each block is one observation: means and their standard errors over blocks
(:func:`cluster_mean`), each block's influence on a least-squares fit (:func:`influence`),
and the intervals of a ratio of two residual RMS on the same held-out samples, given the fits
or with their scatter (:func:`spread`), used by :mod:`imucal.terms.poseholdout`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np


def influence(
    design: np.ndarray, residual: np.ndarray, labels: np.ndarray, n_clusters: int
) -> np.ndarray:
    """Each cluster's influence on a least-squares fit: ``(X'X)^-1 X_c' e_c`` per cluster.

    Their sum of outer products is the cluster-robust covariance of the coefficients (without
    the small-sample factor).

    Parameters
    ----------
    design : ndarray, shape (n, p)
    residual : ndarray, shape (n,) or (n, q)
        The fit's residuals (one column per fitted series).
    labels : ndarray of int, shape (n,)
        Cluster of each row, ``0 .. C - 1``.
    n_clusters : int
        C.

    Returns
    -------
    ndarray, shape (C, p) or (C, p, q)
    """
    e = residual.reshape(len(residual), -1)
    scores = np.zeros((n_clusters, design.shape[1], e.shape[1]))
    np.add.at(scores, labels, design[:, :, None] * e[:, None, :])
    out = np.einsum("ij,cjq->ciq", np.linalg.pinv(design.T @ design), scores)
    return out.reshape(out.shape[:2]) if residual.ndim == 1 else out


def cluster_mean(sums: np.ndarray, counts: np.ndarray) -> tuple[float, float]:
    """Mean per sample over blocks, and its standard error with each block one observation.

    ``m = sum_b s_b / N`` and ``se = sqrt(B / (B - 1) sum_b (s_b - m n_b)^2) / N`` over the ``B``
    blocks, ``s_b`` a block's sum (of squares, or of their difference), ``n_b`` its samples and
    ``N`` all samples: the ratio estimator's cluster-robust standard error with the small-sample
    factor ``B / (B - 1)``. NaN for both without samples, NaN for the error with one block.

    Parameters
    ----------
    sums, counts : ndarray
        Each block's sum and number of samples, shape (B,).
    """
    n, b = counts.sum(), len(counts)
    if not n:
        return np.nan, np.nan
    m = sums.sum() / n
    if b < 2:
        return m, np.nan
    return m, np.sqrt(b / (b - 1) * np.sum((sums - m * counts) ** 2)) / n


def block_sums(
    x: np.ndarray, t_s: np.ndarray, block_s: float, origin_s: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Sums of ``x`` (n,) over consecutive ``block_s`` blocks of ``t_s`` from ``origin_s`` (its
    first time by default), and their counts: the blocks with samples, in time order."""
    if not len(x):
        return x, x
    k = block_index(t_s, block_s, t_s[0] if origin_s is None else origin_s)
    n = np.bincount(k)
    return np.bincount(k, x)[n > 0], n[n > 0].astype(float)


def block_index(t_s: np.ndarray, block_s: float, origin_s: float) -> np.ndarray:
    """Index of the ``block_s`` block from ``origin_s`` each time of ``t_s`` falls in."""
    return ((t_s - origin_s) // block_s).astype(int)


def spread(
    squares: Mapping[str, tuple],
    ids: np.ndarray,
    fit_influence: Mapping[str, np.ndarray],
    comparisons: Sequence[tuple[str, str, str]],
) -> dict:
    """Standard errors of the RMS and 95 % intervals of their ratios over long blocks.

    Each block of ``se_block_s`` counts as one independent observation (the residuals are
    correlated within it, little across). The standard error of a mean square ``m`` is
    ``sqrt(B / (B - 1) sum_b (s_b - m n_b)^2) / N`` over the ``B`` held-out blocks (``s_b`` the
    sum of squares, ``n_b`` the samples, ``N`` all samples), that of the RMS half of it
    relative. A ratio of two RMS on the same samples is compared on the log of its mean
    squares by the delta method, each block's influence on it summed over two sources:

    * the held-out samples, given the fitted models: ``(s_b - m n_b) / (m N)`` per method;
    * the fits: each block of the fit poses moves the fitted coefficients by its influence
      (:func:`influence`), and they move the held-out sum of squares by its gradient
      (``fit_influence``, already the product), divided by that sum of squares.

    A block that is both (a pose held out here and fitted on for another pose's prediction,
    as in the summary over all held-out poses) adds both before squaring. The variance is
    ``B / (B - 1)`` times the sum of the squared influences per source (the held-out blocks,
    the fit blocks that are not held out; a single such fit block joins the held-out ones),
    Student's t with Satterthwaite's degrees of freedom over the two, and the interval is at
    least as wide as the one given the fits. The delta method is linear in the coefficients:
    near a method's best fit its loss from the fit's scatter is quadratic and always positive,
    which it leaves out.

    Two questions, two intervals: ``..._given_fits`` (the held-out samples alone) says whether
    these fitted models differ on this pose by more than its noise; the interval with the
    fits' scatter whether the two methods differ by more than their fits scatter, as they
    would on another recording of the same part.

    Parameters
    ----------
    squares : mapping of str to (ndarray, ndarray)
        Method (``none``, ``term``, a peer) -> sums of its squared residuals over the held-out
        blocks and the samples per block, each shape (B,).
    ids : ndarray of int, shape (B,)
        The held-out blocks' indices among all blocks of the session (see ``fit_influence``).
    fit_influence : mapping of str to ndarray, shape (C,)
        Method -> per block of the session, its influence through the fit on the method's
        held-out sum of squares (unit of the squares; zero for the blocks no fit saw and for
        a method without coefficients).
    comparisons : sequence of (str, str, str)
        The ratios to compute: (name, numerator method, denominator method).

    Returns
    -------
    dict
        ``rms_<method>_se``; per comparison its RMS ratio ``<name>`` with ``<name>_ci95`` and
        ``<name>_ci95_given_fits``; ``clusters`` (B held-out blocks) and ``fit_clusters``
        (blocks of the fits that are not held out).
    """
    counts = next(iter(squares.values()))[1]
    n, b = counts.sum(), len(counts)
    names = list(comparisons)
    held = np.zeros(len(next(iter(fit_influence.values()))), bool)
    held[ids] = True
    fitted = ~held & np.any([f != 0 for f in fit_influence.values()], axis=0)
    out = {"clusters": b, "fit_clusters": int(fitted.sum())}
    if b < 2 or not n:
        nan = float("nan")
        out |= {f"rms_{m}_se": nan for m in squares}
        for name, *_ in names:
            out |= {name: nan, f"{name}_ci95": [nan, nan], f"{name}_ci95_given_fits": [nan, nan]}
        return out
    ms = {m: sums.sum() / n for m, (sums, _) in squares.items()}
    out |= {
        f"rms_{m}_se": float(cluster_mean(*squares[m])[1] / (2 * np.sqrt(ms[m]))) for m in squares
    }
    for name, a, c in names:
        log_ratio = np.log(ms[a] / ms[c])
        given = (squares[a][0] - ms[a] * counts) / ms[a] - (squares[c][0] - ms[c] * counts) / ms[c]
        phi = (fit_influence[a] / ms[a] - fit_influence[c] / ms[c]) / n
        phi[ids] += given / n
        if fitted.sum() >= 2:
            parts = [_part(phi[held], b), _part(phi[fitted], int(fitted.sum()))]
        else:  # a single fit block not held out has no spread of its own: it joins the other
            pool = held | fitted
            parts = [_part(phi[pool], int(pool.sum()))]
        given_fits = _interval(log_ratio, [_part(given / n, b)])
        with_fits = _interval(log_ratio, parts)
        out[name] = float(np.exp(0.5 * log_ratio))
        out[f"{name}_ci95_given_fits"] = given_fits
        # the fits' scatter only widens (Satterthwaite's degrees of freedom could narrow it)
        out[f"{name}_ci95"] = [min(with_fits[0], given_fits[0]), max(with_fits[1], given_fits[1])]
    return out


def verdict_of(interval: Sequence[float]) -> str:
    """The term against another method from the interval of their RMS ratio (NaN: within
    noise)."""
    lo, hi = interval
    return "better" if hi < 1.0 else "worse" if lo > 1.0 else "within noise"


def _part(phi: np.ndarray, blocks: int) -> tuple[float, int]:
    """A source's variance, ``B / (B - 1) sum phi^2`` over its ``B`` blocks, and ``B - 1``."""
    if blocks < 2:
        return 0.0, 0
    return blocks / (blocks - 1) * float(np.sum(phi**2)), blocks - 1


def _interval(log_ratio: float, parts: Sequence[tuple[float, int]]) -> list[float]:
    """95 % interval of an RMS ratio from its log mean-square ratio and the variances of its
    sources (Student's t with Satterthwaite's degrees of freedom)."""
    # imported here: scipy.stats costs about 0.4 s, and the workflow's parse imports this module
    from scipy.stats import t as student_t

    parts = [(v, d) for v, d in parts if v > 0 and d > 0]
    if not parts:
        return [float(np.exp(0.5 * log_ratio))] * 2
    var = sum(v for v, _ in parts)
    dof = var**2 / sum(v**2 / d for v, d in parts)
    half = float(student_t.ppf(0.975, dof)) * np.sqrt(var)
    return [float(np.exp(0.5 * (log_ratio + k * half))) for k in (-1, 1)]
