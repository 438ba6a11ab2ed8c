"""Declared section lists of a recording: JSON or CSV lists of labelled sample ranges, the
Ferraris session labels (mad-lab-fau/imucal), or runs of a label column.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from imucal import io
from imucal.columns import AXES
from imucal.io.readers.declaration import DeclarationError

#: Meaning of the labels of a Ferraris session (mad-lab-fau/imucal): ``<axis>_p`` a static face
#: with that axis pointing up, ``<axis>_a`` pointing down, ``<axis>_rot`` a full turn about it.
FERRARIS_LABELS: dict[str, dict] = {
    **{f"{a}_p": {"kind": "position", "up": f"+{a}"} for a in AXES},
    **{f"{a}_a": {"kind": "position", "up": f"-{a}"} for a in AXES},
    **{f"{a}_rot": {"kind": "phase", "axis": a, "angle_deg": 360.0} for a in AXES},
}


#: Optional columns of a CSV section list besides ``label``, ``start``, ``end``.
SECTION_CSV_OPTIONAL = ("kind", "axis", "up", "angle_deg", "rate_dps")


def read_sections(
    spec: Mapping[str, Any],
    *,
    where: str,
    t_s: np.ndarray,
    primary_t_s: np.ndarray,
    labels: np.ndarray | None = None,
) -> list[dict]:
    """Sections of a recording as manual segment entries (the ``segments`` override format).

    Parameters
    ----------
    spec : mapping
        The ``sections`` declaration: ``recording``, and ``file`` with ``format``
        (``ferraris_json`` or ``csv``) and ``index`` (``sample`` or ``time``), or
        ``from_column``; optional ``labels`` (label -> kind, axis, up, angle_deg, rate_dps).
    where : str
        ``"<dataset.yaml>: sections"``, prefix of the error messages.
    t_s : ndarray, shape (n,)
        Times of the ingested recording, s.
    primary_t_s : ndarray, shape (m,)
        Times of the samples a sample index counts (the first stream of the recording), s.
    labels : ndarray of str, shape (n,), optional
        The ``from_column`` value of every row of the ingested recording.

    Returns
    -------
    list of dict
        ``label``, ``kind``, ``start_s``, ``end_s``, and where known ``axis``, ``up``,
        ``angle_deg``, ``rate_dps``. Sample index ranges are ``[start, end)`` (end exclusive,
        as Python slices and imucal's ``data.iloc[start:end]``): ``start_s = t[start]``,
        ``end_s = t[end - 1]``; time ranges are ``start <= t_s <= end``. A run of one label in
        ``from_column`` is one section (a label repeated in separate runs is an error).

    Raises
    ------
    DeclarationError
        Unknown label (no meaning given), index outside the recording, reversed range.
    RawDataError, FileNotFoundError
        The section file cannot be read.
    """
    meanings = {**FERRARIS_LABELS, **dict(spec.get("labels") or {})}
    if "from_column" in spec:
        ranges = _label_runs(labels, spec["from_column"], where)
        index = "sample_rows"
        source = f"column {spec['from_column']!r}"
    else:
        path = Path(spec["file"])
        if not path.is_file():
            raise FileNotFoundError(f"{where}.file: {path} not found; expected an existing file")
        fmt = spec.get("format", "ferraris_json")
        ranges = _section_json(path) if fmt == "ferraris_json" else _section_csv(path)
        index = spec.get("index", "sample")
        source = str(path)
    out = []
    for row in ranges:
        label = row["label"]
        meaning = {k: row[k] for k in SECTION_CSV_OPTIONAL if row.get(k) not in (None, "")}
        if "kind" not in meaning:
            if label not in meanings:
                raise DeclarationError(
                    f"{where}.labels.{label}",
                    f"label {label!r} of {source} has no meaning",
                    "a labels entry with its kind (x_p .. z_rot of a Ferraris session are known)",
                )
            meaning = {**meanings[label], **meaning}
        start, end = row["start"], row["end"]
        if index == "time":
            start_s, end_s = float(start), float(end)
        else:
            times = t_s if index == "sample_rows" else primary_t_s
            n = times.size
            if not (0 <= start < end <= n):
                raise DeclarationError(
                    f"{where}",
                    f"section {label!r} of {source}: samples {start}..{end} (end exclusive) "
                    f"of a recording with {n}",
                    f"0 <= start < end <= {n}",
                )
            start_s, end_s = float(times[int(start)]), float(times[int(end) - 1])
        if not start_s < end_s:
            raise DeclarationError(
                f"{where}",
                f"section {label!r} of {source}: {start_s} s to {end_s} s",
                "start < end",
            )
        entry = {"label": str(label), "start_s": start_s, "end_s": end_s, **meaning}
        if "angle_deg" in entry:
            entry["angle_deg"] = float(entry["angle_deg"])
        out.append(entry)
    return sorted(out, key=lambda e: e["start_s"])


def _section_json(path: Path) -> list[dict]:
    data = io.read_json(path)
    if not isinstance(data, dict):
        raise io.RawDataError(
            path, None, f"a JSON {type(data).__name__}", '{"label": {"start": ., "end": .}}'
        )
    rows = []
    for label, value in data.items():
        if not (isinstance(value, dict) and {"start", "end"} <= set(value)):
            raise io.RawDataError(
                path, None, f"{label!r}: {value!r}", '{"start": <int>, "end": <int>}'
            )
        rows.append({"label": label, "start": value["start"], "end": value["end"]})
    return rows


def _section_csv(path: Path) -> list[dict]:
    table = pd.read_csv(path, dtype=str, keep_default_na=False, skipinitialspace=True)
    missing = [c for c in ("label", "start", "end") if c not in table.columns]
    if missing:
        raise io.RawDataError(
            path,
            1,
            f"missing column(s) {missing} in {list(table.columns)}",
            "label,start,end[,kind,axis,up,angle_deg,rate_dps]",
        )
    rows = []
    for i, rec in enumerate(table.to_dict("records")):
        try:
            start, end = float(rec["start"]), float(rec["end"])
        except ValueError:
            raise io.RawDataError(
                path, i + 2, f"start {rec['start']!r}, end {rec['end']!r}", "numbers"
            ) from None
        row = {"label": rec["label"], "start": start, "end": end}
        for key in SECTION_CSV_OPTIONAL:
            if rec.get(key, "") != "":
                row[key] = float(rec[key]) if key in ("angle_deg", "rate_dps") else rec[key]
        rows.append(row)
    for row in rows:  # sample indices are integers
        for key in ("start", "end"):
            if float(row[key]).is_integer():
                row[key] = int(row[key])
    return rows


def _label_runs(labels: np.ndarray | None, column: str, where: str) -> list[dict]:
    if labels is None:
        raise DeclarationError(
            f"{where}.from_column", f"column {column!r} not read", "a column of the recording"
        )
    values = np.asarray(labels, dtype=str)
    change = np.flatnonzero(values[1:] != values[:-1]) + 1
    starts = np.concatenate(([0], change))
    ends = np.concatenate((change, [values.size]))
    rows, seen = [], {}
    for a, b in zip(starts, ends):
        label = values[a]
        if label == "":
            continue
        if label in seen:
            raise DeclarationError(
                f"{where}.from_column",
                f"label {label!r} of column {column!r} in two runs (rows {seen[label]} and {a})",
                "each label in one run of rows",
            )
        seen[label] = int(a)
        rows.append({"label": label, "start": int(a), "end": int(b)})
    return rows
