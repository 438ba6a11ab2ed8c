"""The gap diagnosis of a magnetometer session without any rest: the residual of its field fit.

A magnetometer turned by hand through many orientations for its ellipsoid fit has no rest to
measure a noise on and no reference to compare with; what it does have is its fit: calibrated
by the session's own ``partial/calibration.json``, every reading should have the norm of the
field. So the twin (:class:`FieldFitTwin`) replays the session's own fitted field directions
(the calibrated readings, normalised) through the inverse of that calibration, adds the
session's white noise per axis and rounds to the quantisation step; a replica is measured with
the same calibration, not refitted (the fit has 9 parameters against thousands of samples:
what refitting takes out of the residual is below its noise). The statistics are those of the
fit residual ``r = |h| - 1`` (:func:`field_fit_statistics`): its RMS, its slow part (a field
that changes in time, or with the position of the module) and its dependence on the direction
beyond the ellipsoid (a polynomial of degree 3 in the direction).

The noise is estimated from the high-frequency part of the readings (:func:`moving_white`):
the second differences of a slowly moving signal are its noise's (``6 sigma^2`` for white
noise) as long as the motion's own second difference, ``omega^2 |m| dt^2``, stays below it
(about 3 counts for 1 rad/s at 50 Hz on a field of 8000 counts), with a robust spread so that
the fastest turns do not enter. That is the assumption, and the limit of this null: anything
the readings do beyond white noise about the fitted directions (a field that varies, a filter
that lags the turns, a nonlinear response) opens the gap; no library effect is rendered
(``not_observable`` says why), so the verdict names what the twin lacks.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from imucal import errormodel
from imucal.columns import SENSOR_COLUMNS, TIME
from imucal.gap.library import not_observable, scope_library
from imucal.gap.scoring import DiagnosisSettings, scope_diagnosis
from imucal.gap.statictwin import quantum
from imucal.gap.statistics import HALVES
from imucal.gap.twin import Replica
from imucal.sim.effects import stream_rng

#: Fewest magnetometer samples for a fit residual's null.
MIN_SAMPLES = 1000
#: Window of the residual's slow part (s).
SLOW_S = 1.0
#: Degree of the direction polynomial of the residual.
DEGREE = 3


def moving_white(x: np.ndarray) -> np.ndarray:
    """White-noise std per axis of a slowly moving signal, from its second differences.

    Parameters
    ----------
    x : ndarray, shape (n, 3)
        Readings (SI), n >= 3.

    Returns
    -------
    ndarray, shape (3,)
        ``1.4826 MAD(d2) / sqrt(6)`` per axis, ``d2`` the second differences (module
        docstring: the motion's second difference is assumed below the noise's).

    Raises
    ------
    ValueError
        If ``x`` is not (n >= 3, 3).
    """
    x = np.asarray(x, dtype=float)
    if x.ndim != 2 or x.shape[1] != 3 or len(x) < 3:
        raise ValueError(f"readings must have shape (n >= 3, 3), got {x.shape}")
    d2 = np.diff(x, n=2, axis=0)
    mad = np.median(np.abs(d2 - np.median(d2, axis=0)), axis=0)
    return 1.4826 * mad / np.sqrt(6.0)


def _basis(u: np.ndarray) -> np.ndarray:
    """Monomials of the direction up to :data:`DEGREE`, shape (n, k)."""
    cols = [np.ones(len(u))]
    for d in range(1, DEGREE + 1):
        for i in range(d + 1):
            for j in range(d + 1 - i):
                cols.append(u[:, 0] ** i * u[:, 1] ** j * u[:, 2] ** (d - i - j))
    return np.column_stack(cols)


@dataclass(frozen=True)
class FieldFit:
    """A magnetometer recording and the calibration its residual is measured with.

    Attributes
    ----------
    t_s : ndarray, shape (n,)
        Sample times (s).
    mag : ndarray, shape (n, 3)
        Readings (the ingested unit).
    matrix : ndarray, shape (3, 3)
    bias : ndarray, shape (3,)
        The session's calibration: calibrated ``matrix @ (mag - bias)``, norm 1.
    """

    t_s: np.ndarray
    mag: np.ndarray
    matrix: np.ndarray
    bias: np.ndarray

    def half(self, half: str | None) -> FieldFit:
        if half is None:
            return self
        n = len(self.t_s)
        sl = slice(0, n // 2) if half == "A" else slice(n // 2, n)
        return FieldFit(self.t_s[sl], self.mag[sl], self.matrix, self.bias)


def field_fit_statistics(fit: FieldFit, half: str | None = None, name: str = "fit") -> dict:
    """Statistics of the fit residual ``r = |matrix (mag - bias)| - 1``.

    Parameters
    ----------
    fit : FieldFit
    half : {None, 'A', 'B'}
        The whole recording, or its first / second half in time.
    name : str
        The recording's name (the locations' segment).

    Returns
    -------
    dict
        ``("field_fit", "mag", "all", name, statistic)`` -> value: ``fit_resid_rms`` (RMS of
        ``r``), ``fit_resid_slow`` (log of the RMS of ``r``'s running mean over
        :data:`SLOW_S` against that of white noise, ``rms(r) / sqrt(w)``),
        ``fit_resid_direction`` (RMS of the least-squares polynomial of degree
        :data:`DEGREE` in the calibrated direction fitted to ``r``).
    """
    f = fit.half(half)
    h = errormodel.apply(f.matrix, f.bias, f.mag)
    norm = np.linalg.norm(h, axis=1)
    r = norm - 1.0
    rate = (len(f.t_s) - 1) / (f.t_s[-1] - f.t_s[0])
    w = max(int(round(SLOW_S * rate)), 2)
    c = np.concatenate([[0.0], np.cumsum(r - r.mean())])
    slow = (c[w:] - c[:-w]) / w
    rms = float(np.sqrt(np.mean(r**2)))
    white = float(np.std(r)) / np.sqrt(w)
    design = _basis(h / norm[:, None])
    coef, *_ = np.linalg.lstsq(design, r, rcond=None)
    key = ("field_fit", "mag", "all", name)
    return {
        (*key, "fit_resid_rms"): max(rms, 1e-300),
        (*key, "fit_resid_slow"): float(np.log(np.sqrt(np.mean(slow**2)) / max(white, 1e-300))),
        (*key, "fit_resid_direction"): max(float(np.sqrt(np.mean((design @ coef) ** 2))), 1e-300),
    }


@dataclass(frozen=True)
class FieldFitTwin:
    """The twin of a magnetometer's tumble: its fitted field directions, its calibration, its
    noise (module docstring).

    Attributes
    ----------
    name : str
        The recording.
    directions : ndarray, shape (n, 3)
        The session's calibrated field directions (unit vectors).
    matrix, bias : ndarray
        The session's magnetometer calibration (shapes (3, 3), (3,)).
    white : ndarray, shape (3,)
        White-noise std per axis of the readings (the ingested unit).
    step : float
        Quantisation step of the readings (0: not rounded).
    t_s : ndarray, shape (n,)
        The recording's sample times (s).
    notes : list of str
    """

    name: str
    directions: np.ndarray
    matrix: np.ndarray
    bias: np.ndarray
    white: np.ndarray
    step: float
    t_s: np.ndarray
    notes: list = field(default_factory=list)

    def describe(self) -> dict:
        """JSON-ready summary."""
        return {
            "recording": self.name,
            "samples": len(self.t_s),
            "noise_white": self.white.tolist(),
            "step": self.step,
            "notes": list(self.notes),
        }

    def replica(self, seed: int, effects: tuple = (), halves: tuple = HALVES) -> Replica:
        """The readings of the fitted directions through the calibration, with fresh noise,
        rounded; ``effects`` must be empty (none is rendered here)."""
        if effects:
            raise ValueError(f"the field fit's twin renders no effect, got {effects}")
        rng = stream_rng(seed, f"noise/field_fit/{self.name}")
        raw = errormodel.invert(self.matrix, self.bias, self.directions)
        raw = raw + rng.standard_normal(raw.shape) * self.white
        if self.step > 0:
            raw = self.step * np.round(raw / self.step)
        fit = FieldFit(self.t_s, raw, self.matrix, self.bias)
        return Replica(
            seed,
            {self.name: fit},
            {h: field_fit_statistics(fit, h, self.name) for h in halves},
        )


def field_fit_part(
    tables: Mapping[str, pd.DataFrame], calibration: Mapping | None, sensitivity: Mapping
) -> tuple[FieldFit, FieldFitTwin] | str:
    """The recording of a session with the most magnetometer samples and its twin, or why
    there is none.

    Parameters
    ----------
    tables : mapping of str to DataFrame
        The session's ingested recordings.
    calibration : dict or None
        ``partial/calibration.json``; its ``mag`` entry is needed.
    sensitivity : dict
        SI per count per sensor from dataset.yaml (the step is estimated from the readings
        where absent).

    Returns
    -------
    (FieldFit, FieldFitTwin) or str
    """
    cal = (calibration or {}).get("mag")
    if not isinstance(cal, dict) or "matrix" not in cal:
        return "the session has no magnetometer calibration"
    best = None
    for name, table in tables.items():
        if not all(c in table.columns for c in SENSOR_COLUMNS["mag"]):
            continue
        x = table[list(SENSOR_COLUMNS["mag"])].to_numpy(dtype=float)
        ok = np.all(np.isfinite(x), axis=1)
        if ok.sum() >= MIN_SAMPLES and (best is None or ok.sum() > len(best[1])):
            best = (name, x[ok], table[TIME].to_numpy(dtype=float)[ok])
    if best is None:
        return f"no recording has {MIN_SAMPLES} magnetometer samples"
    name, x, t = best
    matrix = np.asarray(cal["matrix"], dtype=float)
    bias = np.asarray(cal["bias"], dtype=float)
    h = errormodel.apply(matrix, bias, x)
    step = float(sensitivity.get("mag") or quantum(x))
    white = moving_white(x)
    # the rounding's share of the second differences: a uniform error of step^2 / 12 per sample
    white = np.sqrt(np.maximum(white**2 - step**2 / 12, 0.0))
    notes = [
        f"mag: the session's fitted calibration ({cal.get('method', 'fitted')})",
        "directions: the session's own calibrated field directions, replayed at norm 1",
        "noise: white per axis from the robust spread of the readings' second differences "
        "(assumed to be the noise's: the motion's own second difference is below it), the "
        "rounding's share taken out",
        f"mag: quantisation step {step:.4g}"
        + ("" if sensitivity.get("mag") else " estimated from the readings"),
    ]
    twin = FieldFitTwin(name, h / np.linalg.norm(h, axis=1)[:, None], matrix, bias, white, step,
                        t, notes)  # fmt: skip
    return FieldFit(t, x, matrix, bias), twin


def diagnose_field_fit(
    fit: FieldFit,
    twin: FieldFitTwin,
    *,
    source: str,
    dataset: str,
    settings: DiagnosisSettings = DiagnosisSettings(),
) -> dict:
    """The gap diagnosis of a magnetometer's tumble on its fit residual (module docstring).

    Parameters
    ----------
    fit, twin
        Output of :func:`field_fit_part`.
    source : str
        Why the session is scored on its fit (kept as ``static_source``).
    dataset : str
    settings : DiagnosisSettings

    Returns
    -------
    dict
        diagnosis.json with ``scope`` ``field_fit``, ``static_source``, ``not_observable``,
        ``twin``, ``settings``, ``timing_s``.
    """
    t0 = time.perf_counter()
    stats = {h: field_fit_statistics(fit, h, twin.name) for h in HALVES}
    return scope_diagnosis(
        twin, {twin.name: fit}, stats, scope_library("field_fit"), scope="field_fit",
        static_source=source,
        not_observable=not_observable("field_fit"),
        cannot_show="the fit residual cannot show this effect",
        dataset=dataset, settings=settings, started=t0,
    )  # fmt: skip
