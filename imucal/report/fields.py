"""Generic rendering of nested JSON for the lab report: the warnings at any depth (and those of
the rules' logs) and the dotted-key rows of an artifact.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from imucal.io.logs import read_log_warnings
from imucal.report.numbers import format_value


def _is_scalar(value: Any) -> bool:
    return value is None or isinstance(value, (str, bool, int, float, np.number, np.bool_))


def log_warnings(paths: Sequence[str | Path]) -> list[dict]:
    """The warnings of the rules' logs, repeats counted (:func:`imucal.io.read_log_warnings`).

    Returns
    -------
    list of dict
        ``source`` (the log's path from its ``logs`` folder on, e.g.
        ``logs/gap_diagnose.log``), ``where`` (the logger), ``text`` and ``count``.
    """
    out = []
    for path in map(Path, paths):
        parts = path.parts
        source = (
            "/".join(parts[len(parts) - parts[::-1].index("logs") - 1 :])
            if "logs" in parts
            else path.name
        )
        out += [
            {"source": source, "where": w.logger, "text": w.text, "count": w.count}
            for w in read_log_warnings(path)
        ]
    return out


def collect_warnings(obj: Any, source: str) -> list[dict]:
    """Every item of every list under a key named ``warnings``, at any depth.

    Returns
    -------
    list of dict
        ``source`` (as given), ``where`` (the dotted key path of the list) and ``text``.
    """
    found: list[dict] = []

    def walk(node: Any, where: str) -> None:
        if isinstance(node, Mapping):
            for key, value in node.items():
                path = f"{where}.{key}" if where else str(key)
                if key == "warnings" and isinstance(value, list):
                    found.extend({"source": source, "where": path, "text": str(w)} for w in value)
                else:
                    walk(value, path)
        elif isinstance(node, list):
            for i, value in enumerate(node):
                walk(value, f"{where}[{i}]")

    walk(obj, "")
    return found


def flatten_fields(obj: Mapping) -> dict:
    """Key/value rows and record tables of a nested dict, for a generic rendering.

    Scalars, vectors and matrices of numbers become rows ``(dotted key, formatted value)``;
    a list of dicts becomes a table of its own (one row per dict, one column per scalar key);
    ``warnings`` lists are left out (they have a section of their own).

    Returns
    -------
    dict
        ``rows``: list of ``(key, value)`` strings; ``records``: list of dicts with ``title``,
        ``columns`` and ``rows`` (lists of strings).
    """
    rows: list[tuple[str, str]] = []
    records: list[dict] = []

    def walk(node: Any, where: str) -> None:
        if isinstance(node, Mapping):
            if not node:
                rows.append((where, "(empty)"))
            for key, value in node.items():
                if key == "warnings" and isinstance(value, list):
                    continue
                walk(value, f"{where}.{key}" if where else str(key))
        elif isinstance(node, list) and node and all(isinstance(v, Mapping) for v in node):
            records.append(_record_table(where, node))
        elif isinstance(node, list) and not all(_is_scalar(v) or isinstance(v, list) for v in node):
            for i, value in enumerate(node):
                walk(value, f"{where}[{i}]")
        else:
            rows.append((where, format_value(node)))

    walk(obj, "")
    return {"rows": rows, "records": records}


def _record_table(title: str, items: Sequence[Mapping]) -> dict:
    columns: list[str] = []
    for item in items:
        columns.extend(k for k in item if k not in columns)
    body = [[_cell(item.get(c, "")) for c in columns] for item in items]
    return {"title": title, "columns": columns, "rows": body}


def _cell(value: Any) -> str:
    """A record's field; a nested dict is shown as compact JSON."""
    if isinstance(value, Mapping):
        return json.dumps(value, sort_keys=True, default=str)
    return format_value(value)
