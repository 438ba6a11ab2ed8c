"""A fleet's parameters across units and over time.

The calibration of each session (``calibration.json``, full or partial path) gives per sensor
the bias, the scale factors, the non-orthogonality angles ``xi`` and the misalignment angles
``alpha`` (eqs. 1-11), with the standard deviations the fits report. Across units, a unit is an
**outlier** in a parameter when its latest session is improbable under the spread of the other
units. It is screened by its robust score against the fleet's median and ``1.4826 x MAD``
(which a few bad units cannot inflate as they would a standard deviation) beyond ``z``, and
confirmed by the prediction t-test against the mean ``m`` and standard deviation ``s`` of the
``k`` units not screened, ``t = (x - m) / (s sqrt(1 + 1/k)) ~ t(k - 1)``, at the two-sided
probability of ``z`` Gaussian standard deviations (``z = 5``: 5.7e-7). The confirmation matters
for small fleets: the MAD of a dozen units is uncertain by a third, so robust scores alone flag
ordinary units. Over time, the **drift** of a unit is the change of each
parameter between its consecutive sessions, per day, scored against the reported standard
deviations where the fits give them.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd
from scipy import stats

from imucal.columns import AXES, SENSORS

#: Parameters of a sensor's calibration as a fleet compares them: name -> (JSON key, unit key).
PARAMETERS = {"bias": "bias", "scale": "scale", "xi_rad": "xi_rad", "alpha_rad": "alpha_rad"}
#: Fewest units for the outlier test: the median and MAD of fewer say little.
MIN_UNITS = 5
#: MAD of a Gaussian sample -> its standard deviation.
MAD_TO_STD = 1.4826
#: Columns of :func:`parameter_table`.
TABLE_COLUMNS = (
    "dataset", "serial", "date", "sensor", "parameter", "axis", "value", "std", "unit",
)  # fmt: skip


def _unit(sensor_cal: Mapping, parameter: str) -> str:
    if parameter == "bias":
        return str(sensor_cal.get("unit_in", ""))
    return "rad" if parameter.endswith("_rad") else "1"


def parameter_table(calibrations: Mapping[str, Mapping], sheet: pd.DataFrame) -> pd.DataFrame:
    """Every parameter of every session as one row.

    Parameters
    ----------
    calibrations : dict of str to dict
        Dataset -> its calibration JSON (:meth:`imucal.calibration.ImuCalibration.to_dict`, or
        a partial session's, which lists the sensors it could not calibrate under ``missing``).
    sheet : DataFrame
        :func:`imucal.fleet.read_sample_sheet`; every dataset of ``calibrations`` must be in it.

    Returns
    -------
    DataFrame
        Columns :data:`TABLE_COLUMNS`; ``std`` is NaN where the fit reports none. Sensors a
        session did not calibrate have no rows.
    """
    meta = sheet.set_index("dataset")
    unknown = sorted(set(calibrations) - set(meta.index))
    if unknown:
        raise ValueError(f"calibrations of {unknown} have no row in the sample sheet")
    rows = []
    for dataset, cal in calibrations.items():
        for sensor in SENSORS:
            sc = cal.get(sensor)
            if not isinstance(sc, Mapping) or "matrix" not in sc:
                continue
            stds = sc.get("std") or {}
            for parameter, key in PARAMETERS.items():
                values = np.asarray(sc[key], dtype=float)
                std = np.asarray(stds.get(key, [np.nan] * 3), dtype=float)
                for j, axis in enumerate(AXES):
                    rows.append({
                        "dataset": dataset, "serial": meta.at[dataset, "serial"],
                        "date": meta.at[dataset, "date"], "sensor": sensor,
                        "parameter": parameter, "axis": axis, "value": float(values[j]),
                        "std": float(std[j]), "unit": _unit(sc, parameter),
                    })  # fmt: skip
    return pd.DataFrame(rows, columns=list(TABLE_COLUMNS))


def latest_per_unit(table: pd.DataFrame) -> pd.DataFrame:
    """The rows of each unit's latest session (the last in the sheet among equal dates)."""
    last = table.sort_values("date", kind="stable").groupby("serial")["dataset"].last()
    return table[table["dataset"].isin(set(last))]


def flag_outliers(table: pd.DataFrame, z: float) -> tuple[pd.DataFrame, str | None]:
    """Units whose latest calibration departs from the fleet (see the module docstring).

    Parameters
    ----------
    table : DataFrame
        :func:`parameter_table`.
    z : float
        Gaussian standard deviations of the test (screening threshold and confirmation level).

    Returns
    -------
    scores : DataFrame
        One row per unit and parameter axis of the latest sessions: the columns of the table
        plus ``median``, ``robust_std``, ``z`` (robust score), ``t`` and ``p`` (the prediction
        t-test of a screened value, NaN otherwise) and ``outlier`` (bool). Empty when the fleet
        has fewer than :data:`MIN_UNITS` units.
    note : str or None
        Why no unit was scored, when none was.
    """
    latest = latest_per_unit(table).reset_index(drop=True)
    n_units = latest["serial"].nunique()
    columns = ["median", "robust_std", "z", "t", "p", "outlier"]
    if n_units < MIN_UNITS:
        empty = latest.iloc[:0].assign(**{c: [] for c in columns})
        return empty, f"{n_units} unit(s): the outlier test needs at least {MIN_UNITS}"
    p_level = 2 * stats.norm.sf(z)
    parts = []
    for _, group in latest.groupby(["sensor", "parameter", "axis"], sort=False):
        x = group["value"].to_numpy(dtype=float)
        median = np.median(x)
        robust = MAD_TO_STD * np.median(np.abs(x - median))
        # a parameter identical across units (e.g. an identity fallback) has no spread
        score = (x - median) / max(robust, 1e-9 * max(abs(median), 1.0))
        screened = np.abs(score) > z
        rest = x[~screened]
        t = np.full(len(x), np.nan)
        p = np.full(len(x), np.nan)
        if screened.any() and len(rest) >= 3:
            spread = np.std(rest, ddof=1) * np.sqrt(1 + 1 / len(rest))
            t[screened] = (x[screened] - rest.mean()) / max(spread, 1e-300)
            p[screened] = 2 * stats.t.sf(np.abs(t[screened]), df=len(rest) - 1)
        parts.append(group.assign(
            median=median, robust_std=robust, z=score, t=t, p=p, outlier=screened & (p < p_level)
        ))  # fmt: skip
    return pd.concat(parts).sort_index(), None


def drift_table(table: pd.DataFrame) -> pd.DataFrame:
    """Change of each parameter between consecutive sessions of the same unit.

    Parameters
    ----------
    table : DataFrame
        :func:`parameter_table`.

    Returns
    -------
    DataFrame
        Columns ``serial``, ``sensor``, ``parameter``, ``axis``, ``unit``, ``from``, ``to``
        (datasets), ``days``, ``change`` (later minus earlier), ``per_day`` (NaN for sessions on
        the same day) and ``z`` (``change / sqrt(std_1^2 + std_2^2)``, NaN where a std is
        unknown).
    """
    rows = []
    keys = ["serial", "sensor", "parameter", "axis"]
    for key, group in table.sort_values("date", kind="stable").groupby(keys, sort=True):
        g = group.reset_index(drop=True)
        for a, b in zip(g.index[:-1], g.index[1:]):
            days = float((g.at[b, "date"] - g.at[a, "date"]) / pd.Timedelta(days=1))
            change = g.at[b, "value"] - g.at[a, "value"]
            combined = np.hypot(g.at[a, "std"], g.at[b, "std"])
            rows.append({
                **dict(zip(keys, key, strict=True)), "unit": g.at[a, "unit"],
                "from": g.at[a, "dataset"], "to": g.at[b, "dataset"], "days": days,
                "change": float(change), "per_day": float(change / days) if days > 0 else np.nan,
                "z": float(change / combined) if combined > 0 else np.nan,
            })  # fmt: skip
    columns = [*keys, "unit", "from", "to", "days", "change", "per_day", "z"]
    return pd.DataFrame(rows, columns=columns)


def summarize_fleet(
    sheet: pd.DataFrame,
    calibrations: Mapping[str, Mapping],
    calibration_paths: Mapping[str, str],
    *,
    outlier_z: float,
    drift_z: float,
) -> tuple[dict, pd.DataFrame, pd.DataFrame]:
    """Everything the fleet report says, as JSON-ready data.

    Parameters
    ----------
    sheet : DataFrame
        :func:`imucal.fleet.read_sample_sheet`.
    calibrations : dict of str to dict
        Dataset -> calibration JSON, for every row of the sheet.
    calibration_paths : dict of str to str
        Dataset -> path of that JSON (for the store).
    outlier_z : float
        Threshold of :func:`flag_outliers`.
    drift_z : float
        Changes between sessions listed when ``|z|`` exceeds it.

    Returns
    -------
    summary : dict
        ``n_units``, ``n_sessions``, ``outlier_z``, ``outlier_note``, ``outliers`` (flagged
        rows), ``outlier_units`` (serials), ``drift_z``, ``drift`` (rows beyond it),
        ``store_index``.
    table : DataFrame
        :func:`parameter_table`.
    scores : DataFrame
        :func:`flag_outliers`.
    """
    from imucal.fleet.store import store_index

    missing = sorted(set(sheet["dataset"]) - set(calibrations))
    if missing:
        raise ValueError(f"sessions {missing} of the sample sheet have no calibration")
    table = parameter_table(calibrations, sheet)
    scores, note = flag_outliers(table, outlier_z)
    drift = drift_table(table)
    flagged = scores[scores["outlier"]] if len(scores) else scores
    listed = drift[drift["z"].abs() > drift_z]
    summary = {
        "n_units": int(sheet["serial"].nunique()),
        "n_sessions": len(sheet),
        "outlier_z": outlier_z,
        "outlier_note": note,
        "outliers": _records(flagged),
        "outlier_units": sorted(flagged["serial"].unique().tolist()) if len(flagged) else [],
        "drift_z": drift_z,
        "drift": _records(listed),
        "store_index": store_index(sheet, calibration_paths),
    }
    return summary, table, scores


def _records(frame: pd.DataFrame) -> list[dict]:
    out = frame.copy()
    if "date" in out.columns:
        out["date"] = out["date"].dt.strftime("%Y-%m-%d")
    return out.to_dict(orient="records")
