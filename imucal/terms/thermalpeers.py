"""The peers' temperature models that the pose hold-out compares the term with.

Two methods that ship in other tools, each written here from its source (the hold-out of
:mod:`imucal.terms.poseholdout` needs them on every fold, so they live in the package; the
benchmark ``tests/benchmarks/peers`` checks the first against scikit-diveMove's own code):

* **IMUcalibrate** (scikit-diveMove, ``skdiveMove/imutools/imucalibrate.py``,
  ``IMUcalibrate.build_tmodels`` at commit 76196a6, wheel 0.4.0): per period (one static pose),
  the signal smoothed by a Savitzky-Golay filter (window 119 samples, order 1: the settings of
  its own test and docs example, 2 min at 1 Hz), then per axis an ordinary least-squares line
  ``signal ~ temperature`` with the period's own intercept and slope. A model belongs to one
  period; it is applied to other data as ``x - (x_hat(T) - x_hat(T_alpha))``, so on a held-out
  pose (its constant removed) only the period's slope acts. The hold-out applies each fit
  pose's model on its own (:func:`per_period_line`), as the peer's ``apply_model`` takes one
  period's model per axis.
* **PX4's thermal calibration** (PX4-Autopilot, ``Tools/process_sensor_caldata.py`` at commit
  00f5c319563d03d2ce482dbd1b53dff25b5a7f34): per sensor axis, a median filter of 31 samples,
  the accelerometer's median removed (``correction = x - median(x)``), the samples averaged in
  2000 equal bins of temperature (``resampleWithDeltaX``), and ``numpy.polyfit`` of order 3 in
  ``T - TREF``, ``TREF`` the middle of the temperature span. PX4 fits one log in one
  orientation; here the fit poses are pooled, each with its own median removed (the script's
  constant, one per pose: :func:`px4_cubic`).

Each returns a :class:`PeerFit`: the powers of ``T`` it predicts with (no constant: the
held-out pose's constant is removed), the fitted coefficients and each cluster's influence on
them (for the intervals of :func:`imucal.terms.blockspread.spread`), as the term has.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.signal import medfilt, savgol_filter

from imucal.terms.blockspread import influence

#: IMUcalibrate's Savitzky-Golay window (samples) and order, as its test and docs use them.
SAVGOL_WINDOW = 119
SAVGOL_ORDER = 1
#: PX4's median filter (samples), temperature bins and polynomial order.
PX4_MEDIAN_KERNEL = 31
PX4_BINS = 2000
PX4_ORDER = 3


def peer_names(n_fit: int) -> list[str]:
    """The peers' methods of a hold-out with ``n_fit`` fit poses: ``imucal_1 .. imucal_n`` (the
    IMUcalibrate model of each fit pose, in time order) and ``cubic``."""
    return [f"imucal_{k}" for k in range(1, n_fit + 1)] + ["cubic"]


def peer_label(name: str) -> str:
    """What a peer method of :func:`peer_names` is, for the tables."""
    if name == "cubic":
        return "per-axis cubic in temperature, PX4's form (fit poses pooled, each median removed)"
    return f"IMUcalibrate, the model of fit pose {name.split('_')[1]} (in time order) alone"


@dataclass(frozen=True)
class PeerFit:
    """A fitted peer model of one axis.

    Attributes
    ----------
    coef : ndarray, shape (p,)
        Coefficients of ``(T - reference_c)^1 .. ^p`` (unit of the readings per K^k).
    reference_c : float
        deg C.
    influence : ndarray, shape (C, p)
        Each cluster's influence on ``coef`` (:func:`~imucal.terms.blockspread.influence`).
    """

    coef: np.ndarray
    reference_c: float
    influence: np.ndarray

    def powers(self, temp_c: np.ndarray) -> np.ndarray:
        """``(T - reference_c)^k``, k = 1 .. p, shape (n, p)."""
        d_t = np.asarray(temp_c, dtype=float) - self.reference_c
        return np.column_stack([d_t**k for k in range(1, len(self.coef) + 1)])

    def predict(self, temp_c: np.ndarray) -> np.ndarray:
        """The model's drift at ``temp_c`` (n,), without a constant."""
        return self.powers(temp_c) @ self.coef


def smoothed(values: np.ndarray) -> np.ndarray:
    """IMUcalibrate's Savitzky-Golay filter of one pose's readings (n, 3), along time."""
    if len(values) < SAVGOL_WINDOW:
        raise ValueError(
            f"a pose of {len(values)} samples is shorter than IMUcalibrate's filter window "
            f"({SAVGOL_WINDOW} samples)"
        )
    return savgol_filter(values, SAVGOL_WINDOW, SAVGOL_ORDER, axis=0)


def median_filtered(values: np.ndarray) -> np.ndarray:
    """PX4's median filter of one pose's readings (n, 3), each axis along time."""
    return np.column_stack([medfilt(values[:, j], PX4_MEDIAN_KERNEL) for j in range(3)])


def per_period_line(
    temp_c: np.ndarray, signal: np.ndarray, labels: np.ndarray, n_clusters: int
) -> PeerFit:
    """IMUcalibrate's model of one period and axis: OLS ``signal ~ 1 + T``.

    Parameters
    ----------
    temp_c : ndarray, shape (n,)
        The period's temperatures, deg C.
    signal : ndarray, shape (n,)
        One axis, smoothed (:func:`smoothed`).
    labels : ndarray of int, shape (n,)
        Each sample's cluster among ``n_clusters``.
    n_clusters : int

    Returns
    -------
    PeerFit
        The slope (order 1) about ``reference_c = 0``; the intercept is the period's own.
    """
    design = np.column_stack([np.ones_like(temp_c), temp_c])
    coef, *_ = np.linalg.lstsq(design, signal, rcond=None)
    spread = influence(design, signal - design @ coef, labels, n_clusters)[:, 1:]
    return PeerFit(coef[1:], 0.0, spread)


def bin_means(x: np.ndarray, y: np.ndarray, bins: int = PX4_BINS) -> tuple:
    """PX4's ``resampleWithDeltaX``: means of ``x`` and ``y`` over ``bins`` equal bins of
    ``x`` (the last bin closed), the empty ones left out, and each sample's bin among them."""
    lo, hi = float(np.min(x)), float(np.max(x))
    width = (hi - lo) / bins
    index = (
        np.minimum(((x - lo) / width).astype(int), bins - 1) if width > 0 else np.zeros(len(x), int)
    )
    count = np.bincount(index, minlength=bins)
    kept = np.flatnonzero(count)
    position = np.full(bins, -1)
    position[kept] = np.arange(len(kept))
    n = count[kept].astype(float)
    return (
        np.bincount(index, x, bins)[kept] / n,
        np.bincount(index, y, bins)[kept] / n,
        position[index],
        n,
    )


def px4_cubic(
    temps: Sequence[np.ndarray],
    values: Sequence[np.ndarray],
    labels: Sequence[np.ndarray],
    n_clusters: int,
) -> PeerFit:
    """PX4's per-axis cubic on the pooled fit poses, each pose's median removed.

    Parameters
    ----------
    temps : sequence of ndarray, shape (n_p,)
        Each fit pose's temperatures, deg C.
    values : sequence of ndarray, shape (n_p,)
        One axis of each pose, median-filtered (:func:`median_filtered`).
    labels : sequence of ndarray of int, shape (n_p,)
        Each sample's cluster among ``n_clusters``.
    n_clusters : int

    Returns
    -------
    PeerFit
        ``X1 .. X3`` about ``TREF`` (PX4's ``X0``, the constant, is the held-out pose's own).

    Notes
    -----
    ``polyfit`` on the bin means is linear in the samples: a sample in bin ``b`` of ``n_b``
    moves the coefficients by ``P[:, b] / n_b`` per unit, ``P`` the pseudo-inverse of the bins'
    Vandermonde matrix; each cluster's influence is that weight times the samples' residuals.
    """
    temp = np.concatenate(temps)
    y = np.concatenate([v - np.median(v) for v in values])
    reference_c = 0.5 * (float(temp.min()) + float(temp.max()))
    x_bin, y_bin, where, n = bin_means(temp - reference_c, y)
    vander = np.column_stack([x_bin**k for k in range(PX4_ORDER + 1)])
    pinv = np.linalg.pinv(vander)
    coef = pinv @ y_bin
    d_t = temp - reference_c
    residual = y - np.column_stack([d_t**k for k in range(PX4_ORDER + 1)]) @ coef
    weights = pinv[:, where] / n[where]  # (order + 1, n)
    spread = np.zeros((n_clusters, PX4_ORDER + 1))
    np.add.at(spread, np.concatenate(labels), (weights * residual).T)
    return PeerFit(coef[1:], reference_c, spread[:, 1:])
