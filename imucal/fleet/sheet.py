"""The sample sheet: one row per calibration session of a fleet of sensors.

A tab-separated file (as the units sheets of the Snakemake workflows catalogue) with the columns
:data:`SHEET_COLUMNS`: ``dataset`` (the session's name, ``[a-z0-9_]+``, unique), ``path`` (its
folder with ``dataset.yaml``; relative paths from the sheet's folder), ``serial`` (the sensor
unit), ``date`` (ISO 8601 day of the session, ``YYYY-MM-DD``) and ``operator``. Extra columns are
kept. Every row is checked against the schema ``imucal/io/schemas/sessions.schema.yaml``; an
error names the file, the line and what was expected.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

import jsonschema
import pandas as pd
import yaml

#: Columns a sample sheet must have (the schema's required properties).
SHEET_COLUMNS = ("dataset", "path", "serial", "date", "operator")


def _row_validator() -> jsonschema.Draft202012Validator:
    text = resources.files("imucal.io").joinpath("schemas/sessions.schema.yaml").read_text()
    return jsonschema.Draft202012Validator(yaml.safe_load(text))


def read_sample_sheet(path: str | Path) -> pd.DataFrame:
    """Read and check a sample sheet.

    Parameters
    ----------
    path : str or Path
        The TSV file.

    Returns
    -------
    DataFrame
        One row per session, the columns :data:`SHEET_COLUMNS` (``path`` absolute, ``date`` a
        ``datetime64`` day) and any extra ones, in the order of the file.

    Raises
    ------
    FileNotFoundError
        If the sheet does not exist.
    ValueError
        If a column is missing, a cell is empty, a dataset name is malformed or repeated, or a
        date is not ``YYYY-MM-DD``; the message names the file and the line.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"sample sheet {path}: no such file")
    sheet = pd.read_csv(path, sep="\t", dtype=str, keep_default_na=False, comment="#")
    missing = [c for c in SHEET_COLUMNS if c not in sheet.columns]
    if missing:
        raise ValueError(
            f"sample sheet {path}: no column(s) {missing}; expected the tab-separated columns "
            f"{list(SHEET_COLUMNS)}"
        )
    if sheet.empty:
        raise ValueError(f"sample sheet {path}: no session; expected one row per session")
    # the header is line 1; comment lines are not counted by pandas, so find each row's line
    lines = _data_lines(path)
    validator = _row_validator()
    dates = []
    for i, row in enumerate(sheet.to_dict(orient="records")):
        where = f"sample sheet {path}, line {lines[i]}"
        for error in validator.iter_errors(row):
            column = error.path[0] if error.path else "?"
            expected = validator.schema["properties"].get(column, {}).get("description", "")
            raise ValueError(f"{where}: column {column!r}: {error.message} ({expected})")
        try:
            dates.append(pd.Timestamp.fromisoformat(row["date"]).normalize())
        except ValueError:
            raise ValueError(
                f"{where}: date {row['date']!r} is not a day of the calendar"
            ) from None
    repeated = sheet["dataset"][sheet["dataset"].duplicated()].tolist()
    if repeated:
        raise ValueError(
            f"sample sheet {path}: dataset(s) {repeated} repeat; expected unique names"
        )
    out = sheet.copy()
    out["path"] = [str((path.parent / p).resolve()) for p in sheet["path"]]
    out["date"] = pd.to_datetime(dates)
    return out


def _data_lines(path: Path) -> list[int]:
    """Line numbers (1-based) of the data rows: after the header, comments and blanks skipped."""
    numbers = []
    header_seen = False
    for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        if header_seen:
            numbers.append(number)
        header_seen = True
    return numbers
