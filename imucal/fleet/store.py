"""The calibration store: which calibration of a unit is valid at a date.

The store is an index, written as JSON by the ``fleet`` rule (``results/fleet/store.json``):
serial -> the unit's sessions in date order, each with its date, dataset and the path of its
``calibration.json``. A calibration is valid from its session's day until the unit's next one,
so the calibration of serial S valid at date D is the unit's latest session on or before D (as
mad-lab-fau/imucal's management module finds the closest calibration before a recording).
"""

from __future__ import annotations

from collections.abc import Mapping

import pandas as pd


def store_index(sheet: pd.DataFrame, calibration_paths: Mapping[str, str]) -> dict:
    """The store's index of a sample sheet.

    Parameters
    ----------
    sheet : DataFrame
        :func:`imucal.fleet.read_sample_sheet`.
    calibration_paths : dict of str to str
        Dataset -> path of its calibration JSON.

    Returns
    -------
    dict
        Serial -> list of ``{"date": "YYYY-MM-DD", "dataset", "calibration"}`` in date order.
    """
    index: dict[str, list] = {}
    for row in sheet.sort_values("date", kind="stable").itertuples(index=False):
        index.setdefault(str(row.serial), []).append({
            "date": row.date.strftime("%Y-%m-%d"),
            "dataset": row.dataset,
            "calibration": str(calibration_paths[row.dataset]),
        })  # fmt: skip
    return dict(sorted(index.items()))


def calibration_for(index: Mapping[str, list], serial: str, date: str) -> dict:
    """The calibration of ``serial`` valid at ``date`` (its latest session on or before it).

    Parameters
    ----------
    index : dict
        :func:`store_index` (or the JSON it was written to).
    serial : str
    date : str
        ``YYYY-MM-DD``.

    Returns
    -------
    dict
        The index entry: ``date``, ``dataset``, ``calibration`` (path).

    Raises
    ------
    ValueError
        If the serial is not in the store, the date is malformed, or the unit has no
        calibration on or before the date (the message names its first).
    """
    if serial not in index:
        raise ValueError(f"serial {serial!r} is not in the store; it has {sorted(index)}")
    try:
        day = pd.Timestamp.fromisoformat(date).normalize()
    except ValueError:
        raise ValueError(f"date {date!r}; expected YYYY-MM-DD") from None
    valid = [e for e in index[serial] if pd.Timestamp(e["date"]) <= day]
    if not valid:
        first = index[serial][0]["date"]
        raise ValueError(
            f"serial {serial!r} has no calibration on or before {date}; its first is {first}"
        )
    return dict(valid[-1])
