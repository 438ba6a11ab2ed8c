"""The segments table: its rows and frame, and the samples of a recording that a segment holds.

Columns and kinds: :data:`imucal.columns.SEGMENT_COLUMNS`, :data:`imucal.columns.KINDS`
(docs/architecture.md). ``start_index`` .. ``end_index`` are row indices into the ingested table,
end exclusive.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from imucal.columns import SEGMENT_COLUMNS, TIME, column_values, row_bounds


def segment_row(recording, label, kind, t, a, b, axis="", rate_dps=np.nan, sense=0, turns=np.nan,
         up="", angle_deg=np.nan):  # fmt: skip
    return {
        "recording": recording, "label": label, "kind": kind,
        "start_s": float(t[a]), "end_s": float(t[b - 1]), "start_index": int(a), "end_index": int(b),
        "axis": axis, "rate_dps": float(rate_dps), "sense": int(sense), "turns": float(turns),
        "up": up, "angle_deg": float(angle_deg),
    }  # fmt: skip


def segments_frame(rows: list[dict]) -> pd.DataFrame:
    frame = pd.DataFrame(rows, columns=list(SEGMENT_COLUMNS))
    return frame.astype(
        {
            "start_s": float,
            "end_s": float,
            "start_index": np.int64,
            "end_index": np.int64,
            "rate_dps": float,
            "sense": np.int64,
            "turns": float,
            "angle_deg": float,
        }
    )


def to_table_rows(out: pd.DataFrame, keep: np.ndarray) -> pd.DataFrame:
    """Segment row indices into the kept rows -> indices into the whole table (end exclusive)."""
    if len(out):
        out["start_index"] = keep[out["start_index"].to_numpy()]
        out["end_index"] = keep[out["end_index"].to_numpy() - 1] + 1
    return out


def rows_of(segments: pd.DataFrame, recording: str, *kinds: str) -> pd.DataFrame:
    """Rows of ``segments`` of ``recording`` whose kind is one of ``kinds``, in time order."""
    rows = segments[(segments["recording"] == recording) & segments["kind"].isin(kinds)]
    return rows.sort_values("start_index")


def cut(table: pd.DataFrame, rows: pd.DataFrame, columns) -> list[np.ndarray]:
    """The samples of ``columns`` each segment row holds: one array (n_k, len(columns)) a row."""
    return [column_values(table, columns, slice(a, b)) for a, b in row_bounds(rows)]


def cut_finite(
    table: pd.DataFrame, rows: pd.DataFrame, columns
) -> list[tuple[np.ndarray, np.ndarray]]:
    """``(t_s (n_k,), values (n_k, len(columns)))`` per segment row, the rows of the table with
    a NaN in ``columns`` left out (streams merged on time: rows of another sensor)."""
    out = []
    for a, b in row_bounds(rows):
        part = slice(a, b)
        values = column_values(table, columns, part)
        keep = np.isfinite(values).all(axis=1)
        out.append((table[TIME].to_numpy(dtype=float)[part][keep], values[keep]))
    return out
