"""A session cut into two parts that share no sample, for fitting each part on its own.

The check of the shipped standard deviations (:mod:`imucal.validation.consistency`) fits the
same chain on each part; its parts must be independent for the fit at hand. Two ways to cut
(:data:`SCHEMES`), tried in this order:

* ``halves``: each recording cut in two at the middle of its middle rest (one static recording:
  at its middle), every part a contiguous recording of its own. The parts share no sample and no
  turn, so this suits every fit, turns between poses included, and it sees an error that
  changes over the session (a wandering bias, a warm-up) as well as one that changes from pose
  to pose. Each half must determine the fit alone (nine orientations for the cube fit; the
  three rotation3d phases fall in different halves, so the paper's protocol cannot use it).
* ``within``: every segment and every motion between segments cut in two halves, the first
  halves one part and the second halves the other (the other part's rows are NaN, "no sample"
  in the ingested tables). Both parts see every pose, phase and run, so every fit determined
  on the session is determined on each part; but what is the same all through a pose (a
  misplaced face) is in both, so this sees the noise and what changes within a segment, and
  it cannot serve a fit that integrates turns (:data:`TURN_STAGES`: both parts would hold half
  of every turn).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd

from imucal.columns import SENSOR_COLUMNS, TIME

#: The ways to cut a session into two independent parts, in the order they are tried.
SCHEMES = ("halves", "within")
#: Stages whose fit integrates the gyroscope over turns (or aligns to a reference along them):
#: the ``within`` scheme gives both parts half of every turn, so they are not independent.
TURN_STAGES = frozenset(
    {
        "gyr_known_rotation",
        "gyr_pose_to_pose",
        "gyr_scale",
        "gyr_reference",
        "acc_reference",
        "mag_reference",
    }
)
#: Rests: the segments a recording is cut in the middle of (``halves``).
REST_KINDS = ("static", "position")

#: One part: its recordings by name and its segments table.
Part = tuple[dict[str, pd.DataFrame], pd.DataFrame]


def split_session(
    tables: Mapping[str, pd.DataFrame], segments: pd.DataFrame, scheme: str
) -> tuple[Part, Part]:
    """Two parts of a session that share no sample.

    Parameters
    ----------
    tables : mapping of str to DataFrame
        Ingested recordings by name (SI units).
    segments : DataFrame
        The session's segments table (row indices into the tables).
    scheme : {'halves', 'within'}
        See the module docstring.

    Returns
    -------
    (tables, segments), (tables, segments)
        The first and the second part; the segments' ``attrs`` (notes) are kept.

    Raises
    ------
    ValueError
        For an unknown scheme.
    """
    if scheme not in SCHEMES:
        raise ValueError(f"unknown scheme {scheme!r}; expected one of {SCHEMES}")
    cut = _cut_in_halves if scheme == "halves" else _cut_within
    parts: tuple[list, list] = ([], [])
    out_tables: tuple[dict, dict] = ({}, {})
    for name, table in tables.items():
        rows = segments[segments["recording"] == name].sort_values("start_index")
        for k, (piece, piece_rows) in enumerate(cut(table, rows)):
            out_tables[k][name] = piece
            parts[k].append(piece_rows)
    out = []
    for k in range(2):
        frame = pd.concat(parts[k], ignore_index=True) if parts[k] else segments.iloc[:0].copy()
        frame.attrs = dict(segments.attrs)
        out.append((out_tables[k], frame))
    return out[0], out[1]


def _cut_row(table: pd.DataFrame, rows: pd.DataFrame) -> int:
    """Where a recording is cut in two: the middle of its middle rest (by count), else the
    middle of the recording."""
    rests = rows[rows["kind"].isin(REST_KINDS)]
    if rests.empty:
        return len(table) // 2
    middle = rests.iloc[len(rests) // 2] if len(rests) > 1 else rests.iloc[0]
    return (int(middle["start_index"]) + int(middle["end_index"])) // 2


def _with_bounds(row: pd.Series, start: int, end: int, t: np.ndarray, shift: int) -> dict:
    """A segment row with new sample bounds (in the whole table) and its times, shifted."""
    out = row.to_dict()
    out.update(
        start_index=start - shift,
        end_index=end - shift,
        start_s=float(t[start]),
        end_s=float(t[end - 1]),
    )
    return out


def _cut_in_halves(table: pd.DataFrame, rows: pd.DataFrame) -> list[tuple]:
    """The first and the second half of a recording, each with its segments (a rest across the
    cut in two pieces of the same label; another segment across it in neither)."""
    cut = _cut_row(table, rows)
    t = table[TIME].to_numpy(dtype=float)
    first, second = [], []
    for _, row in rows.iterrows():
        a, b = int(row["start_index"]), int(row["end_index"])
        if b <= cut:
            first.append(row.to_dict())
        elif a >= cut:
            second.append(_with_bounds(row, a, b, t, cut))
        elif row["kind"] in REST_KINDS:
            first.append(_with_bounds(row, a, cut, t, 0))
            second.append(_with_bounds(row, cut, b, t, cut))
    columns = list(rows.columns)
    return [
        (table.iloc[:cut].reset_index(drop=True), pd.DataFrame(first, columns=columns)),
        (table.iloc[cut:].reset_index(drop=True), pd.DataFrame(second, columns=columns)),
    ]


def _cut_within(table: pd.DataFrame, rows: pd.DataFrame) -> list[tuple]:
    """Every segment and every stretch between segments in two halves; each part keeps its
    halves' rows and has NaN in the sensors' columns on the other part's."""
    n = len(table)
    t = table[TIME].to_numpy(dtype=float)
    edges = sorted({0, n, *rows["start_index"].astype(int), *rows["end_index"].astype(int)})
    first = np.zeros(n, dtype=bool)
    for a, b in zip(edges[:-1], edges[1:]):
        first[a : (a + b) // 2] = True
    halves: tuple[list, list] = ([], [])
    for _, row in rows.iterrows():
        a, b = int(row["start_index"]), int(row["end_index"])
        middle = (a + b) // 2
        if middle > a and b > middle:
            halves[0].append(_with_bounds(row, a, middle, t, 0))
            halves[1].append(_with_bounds(row, middle, b, t, 0))
    sensors = [c for cols in SENSOR_COLUMNS.values() for c in cols if c in table.columns]
    out = []
    for k, mine in enumerate((first, ~first)):
        piece = table.copy()
        piece.loc[~mine, sensors] = np.nan
        out.append((piece, pd.DataFrame(halves[k], columns=list(rows.columns))))
    return out
