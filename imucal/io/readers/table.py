"""The ``table`` reader of a declared entry: delimited text (comma, semicolon, tab or whitespace)
with a header line or column numbers.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from imucal import io
from imucal.io.readers.declaration import DeclarationError, is_array_column

#: Delimiters of the table reader; ``whitespace`` is any run of blanks and tabs.
DELIMITERS = {",": ",", ";": ";", "\t": "\t", "whitespace": r"\s+"}


def read_table(
    entry: Mapping[str, Any],
    path: Path,
    columns: Mapping[str, Any],
    where: str,
    label_column: str | None,
) -> tuple[dict[str, np.ndarray], np.ndarray | None, int]:
    """Delimited text: returns raw float columns by target, the labels and the first data line."""
    delimiter = entry.get("delimiter", ",")
    if delimiter not in DELIMITERS:
        raise DeclarationError(f"{where}.delimiter", f"{delimiter!r}", f"one of {list(DELIMITERS)}")
    skip = int(entry.get("skip_lines", 0))
    header = bool(entry.get("header", True))
    try:
        text = pd.read_csv(
            path,
            sep=DELIMITERS[delimiter],
            header=0 if header else None,
            skiprows=skip,
            dtype=str,
            keep_default_na=False,
            skip_blank_lines=False,
            engine="python" if delimiter == "whitespace" else "c",
            encoding="utf-8-sig",
        )
    except pd.errors.EmptyDataError:
        raise io.RawDataError(
            path, skip + 1, "no header and no data after the skipped lines", "a table"
        ) from None
    except pd.errors.ParserError as err:
        raise io.RawDataError(
            path, None, f"not a {delimiter!r}-delimited table ({err})", "equal cells per line"
        ) from None
    first_line = skip + (2 if header else 1)
    names = [str(c) for c in text.columns]
    if text.shape[0] == 0:
        raise io.RawDataError(path, first_line, "no data rows", "at least one row of samples")
    blank = (text == "").all(axis=1).to_numpy()
    if blank.any():
        row = int(np.flatnonzero(blank)[0])
        raise io.RawDataError(path, first_line + row, "an empty line", "one row per line")

    def position(target: str, source: Any, key: str) -> int:
        if is_array_column(source):
            raise DeclarationError(
                key,
                f"source {list(source)!r} (a column of a named array) in the table {path}",
                "a column name or a 0-based column index (arrays are for matlab and hdf5)",
            )
        if isinstance(source, int):
            if source >= len(names):
                raise DeclarationError(
                    key,
                    f"column index {source} not in {path} ({len(names)} columns: {names})",
                    f"an index 0..{len(names) - 1}",
                )
            return source
        if not header:
            raise DeclarationError(
                key,
                f"column {source!r} by name, but header is false in {path}",
                "a 0-based column index (the file has no header line)",
            )
        if source not in names:
            raise DeclarationError(
                key,
                f"column {source!r} not in {path} (columns: {', '.join(names)})",
                "a column of its header line",
            )
        return names.index(source)

    raw: dict[str, np.ndarray] = {}
    for target, source in columns.items():
        k = position(target, source, f"{where}.columns.{target}")
        raw[target] = _numbers(text.iloc[:, k], path, names[k] if header else k, first_line)
    labels = None
    if label_column is not None:
        try:
            k = position("section", label_column, f"{where}: sections.from_column")
        except DeclarationError:
            k = None
        if k is not None:
            labels = text.iloc[:, k].to_numpy(dtype=str)
    return raw, labels, first_line


def _numbers(cells: pd.Series, path: Path, column: Any, first_line: int) -> np.ndarray:
    """Cells to float64; an empty cell is NaN, anything else that is not a number is an error."""
    values = pd.to_numeric(cells.str.strip(), errors="coerce").to_numpy(dtype=float)
    bad = (
        np.isnan(values)
        & (cells.str.strip() != "").to_numpy()
        & ~cells.str.strip().str.lower().isin(["nan"]).to_numpy()
    )
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise io.RawDataError(
            path, first_line + row, f"column {column!r} holds {cells.iloc[row]!r}", "a number"
        )
    return values
