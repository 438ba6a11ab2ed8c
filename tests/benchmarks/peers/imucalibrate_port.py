"""A port of scikit-diveMove's ``IMUcalibrate.build_tmodels`` (temperature models per period).

Source: repository spluque/scikit-diveMove, file ``skdiveMove/imutools/imucalibrate.py`` at
commit 76196a6 ("Fixed latest warnings about arguments from xarray and pandas", the last commit
that holds the module; e2087eb removed the sub-package), the same code as its 0.4.0 wheel on
PyPI. Rewritten here on arrays; the peer itself needs R (``rpy2`` and the diveMove package) and
cannot be installed whole.

What ``build_tmodels(var, T_alpha, T_brk, use_axis_order, filter_sig, win_len, polyorder)``
does, step by step, for each period in turn (ported below):

1. The period's samples: ``imu.loc[{time: slice(start, stop)}]``, both ends included.
2. With ``filter_sig`` (the default) the signal is smoothed by
   ``scipy.signal.savgol_filter(x, window_length=win_len, polyorder=polyorder, axis=0)``
   (``polyorder`` 1 by default); the temperature is not filtered.
3. ``T_alpha`` defaults to ``numpy.rint`` of the period's mean temperature.
4. Per axis (all three, or with ``use_axis_order`` only the period's axis along gravity),
   ``statsmodels.formula.api.ols("var ~ temperature")``: its own intercept and slope per
   period. With ``T_brk`` the formula is ``var ~ temperature + temp0 + temp1`` with
   ``temp0 = T where T < T_brk else 0`` and ``temp1 = T where T > T_brk else 0`` (a rank-
   deficient design: statsmodels solves it with the pseudo-inverse, so does this port).
5. The prediction at ``T_alpha`` (with ``T_brk``: ``temp0 = T_alpha, temp1 = 0`` below the
   break, else ``temp0 = 0, temp1 = T_alpha``) and the standardised signal
   ``x - (x_hat - x_hat(T_alpha))`` (the docstring's eq. 5).

The standard errors are statsmodels' ``bse`` for OLS (``nonrobust``): ``sqrt(diag(s^2
pinv(X) pinv(X)'))`` with ``s^2`` the residual sum of squares over ``n - rank(X)``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.signal import savgol_filter

#: The window and order of the peer's own test and docs example (1 Hz data: 2 min - 1 sample).
WIN_LEN = int(2 * 60 * 1) - 1
POLYORDER = 1


@dataclass(frozen=True)
class PeriodModel:
    """One period's OLS model of one axis (statsmodels' ``params`` and ``bse``).

    Attributes
    ----------
    params : ndarray, shape (2,) or (4,)
        ``Intercept, temperature`` (and ``temp0, temp1`` with a break), unit of the signal
        (per deg C for the slopes).
    bse : ndarray, same shape
        Their standard errors.
    t_alpha : float
        Reference temperature, deg C.
    at_t_alpha : float
        The model's prediction at ``t_alpha``.
    t_brk : float or None
    nobs : int
    """

    params: np.ndarray
    bse: np.ndarray
    t_alpha: float
    at_t_alpha: float
    t_brk: float | None
    nobs: int

    def predict(self, temp_c: np.ndarray) -> np.ndarray:
        """The model at temperatures ``temp_c`` (n,), as statsmodels' ``fittedvalues``."""
        return _design(np.asarray(temp_c, dtype=float), self.t_brk) @ self.params

    def standardize(self, values: np.ndarray, temp_c: np.ndarray) -> np.ndarray:
        """``x - (x_hat - x_hat(T_alpha))`` (eq. 5 of the peer's docstring)."""
        return values - (self.predict(temp_c) - self.at_t_alpha)


def _design(temp_c: np.ndarray, t_brk: float | None) -> np.ndarray:
    columns = [np.ones_like(temp_c), temp_c]
    if t_brk is not None:
        columns += [np.where(temp_c < t_brk, temp_c, 0.0), np.where(temp_c > t_brk, temp_c, 0.0)]
    return np.column_stack(columns)


def ols(temp_c: np.ndarray, y: np.ndarray, t_brk: float | None = None) -> tuple:
    """statsmodels' OLS of ``y ~ temperature`` (pinv solution): params, bse, residual."""
    x = _design(temp_c, t_brk)
    pinv = np.linalg.pinv(x)
    params = pinv @ y
    residual = y - x @ params
    dof = len(y) - np.linalg.matrix_rank(x)
    scale = residual @ residual / dof
    bse = np.sqrt(np.diag(scale * pinv @ pinv.T))
    return params, bse, residual


def build_tmodels(
    periods: Sequence[tuple[np.ndarray, np.ndarray]],
    *,
    t_alpha: float | None = None,
    t_brk: float | None = None,
    axes: Sequence[Sequence[int]] | None = None,
    filter_sig: bool = True,
    win_len: int = WIN_LEN,
    polyorder: int = POLYORDER,
) -> list[dict[int, PeriodModel]]:
    """The peer's temperature models of one tri-axial variable, one set per period.

    Parameters
    ----------
    periods : sequence of (ndarray, ndarray)
        Per period (its samples, both ends included), the temperature (n,) in deg C and the
        signal (n, 3) in its own unit.
    t_alpha : float, optional
        Reference temperature; default ``rint`` of each period's mean temperature.
    t_brk : float, optional
        Break temperature of the piecewise model.
    axes : sequence of sequence of int, optional
        Per period, the axes to model (``use_axis_order``: the one along gravity); default all.
    filter_sig : bool
        Savitzky-Golay filter the signal before the fit.
    win_len, polyorder : int
        The filter's window (samples, odd) and order.

    Returns
    -------
    list of dict of int to PeriodModel
        Per period, axis index -> model.
    """
    out = []
    for p, (temp, values) in enumerate(periods):
        temp = np.asarray(temp, dtype=float)
        values = np.asarray(values, dtype=float)
        signal = (
            savgol_filter(values, window_length=win_len, polyorder=polyorder, axis=0)
            if filter_sig
            else values
        )
        alpha = float(np.rint(temp.mean())) if t_alpha is None else float(t_alpha)
        models = {}
        for j in range(values.shape[1]) if axes is None else axes[p]:
            params, bse, _ = ols(temp, signal[:, j], t_brk)
            if t_brk is None:
                at = float(params @ [1.0, alpha])
            elif alpha < t_brk:
                at = float(params @ [1.0, alpha, alpha, 0.0])
            else:
                at = float(params @ [1.0, alpha, 0.0, alpha])
            models[j] = PeriodModel(params, bse, alpha, at, t_brk, len(temp))
        out.append(models)
    return out
