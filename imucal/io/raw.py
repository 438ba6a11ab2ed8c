"""Raw files of a session: the IMU CSV log and the MT Manager export, read with pyarrow.

The data contract is ``docs/data-format.md``. Readers check the *format* of a file (header,
cells, which cells may be empty) and report any problem as one :class:`RawDataError` naming
the file, the 1-based line number as a text editor shows it, and what was expected. Checks of
the *content* (time order, packet counter) live in :mod:`imucal.ingest`.
"""

from __future__ import annotations

import difflib
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.csv as pacsv

from imucal.columns import (
    ACC,
    GYR,
    MAG,
    RAW_COLUMNS,
    REF_ACC,
    REF_COUNTER,
    REF_GYR,
    REF_MAG,
    REF_TIME_FINE,
    SEQ,
    TIME,
)

#: Format names recorded in the metadata.
IMU_CSV_FORMAT = "imu-csv"
MT_MANAGER_FORMAT = "mt-manager-ascii"

_RAW_HEADER_TEXT = ",".join(RAW_COLUMNS)
_REF_REQUIRED = (REF_COUNTER, *REF_ACC, *REF_GYR, *REF_MAG)
# Placeholder name for the empty column a trailing delimiter creates (MT Manager writes one).
_TRAILING = "\x00trailing"


class RawDataError(ValueError):
    """A raw file breaks the data contract.

    The message reads ``"<file>, line <n>: <what was found>; expected <what>"`` (without the
    line where the problem is not on one line).

    Attributes
    ----------
    path : Path
        The offending file.
    line : int or None
        1-based line number in the file, as a text editor shows it.
    """

    def __init__(self, path: str | Path, line: int | None, found: str, expected: str) -> None:
        self.path = Path(path)
        self.line = None if line is None else int(line)
        line = self.line
        where = f"{path}, line {line}" if line is not None else f"{path}"
        super().__init__(f"{where}: {found}; expected {expected}")


@dataclass(frozen=True)
class MtManagerExport:
    """An Xsens MT Manager ASCII export as read from disk (columns and units as exported).

    Attributes
    ----------
    table : DataFrame
        ``PacketCounter`` (int64), ``SampleTimeFine`` (int64, 10 kHz ticks, when exported),
        ``Acc_X..Z`` (m/s^2), ``Gyr_X..Z`` (rad/s), ``Mag_X..Z`` (normalised; NaN where
        empty), then any other exported column (float64).
    header : dict
        The ``// key: value`` lines above the column header, e.g. ``{'Update Rate': '100.0Hz'}``.
    update_rate_hz : float or None
        From ``// Update Rate: 100.0Hz``; None when the export does not state it.
    first_line : int
        Line number of the first data row (row ``i`` is on line ``first_line + i``).
    """

    table: pd.DataFrame
    header: dict
    update_rate_hz: float | None
    first_line: int


# --------------------------------------------------------------------------------------------
# Raw IMU CSV


def read_imu_csv(path: str | Path) -> pd.DataFrame:
    """Read a raw IMU log in the native CSV format (raw counts, see ``docs/data-format.md``).

    Parameters
    ----------
    path : str or Path
        CSV file with the header ``t_s,seq,acc_x,...,mag_z`` (then optional numeric extra
        columns), comma-separated, one packet per line.

    Returns
    -------
    DataFrame, shape (n, 11 + extra)
        ``t_s`` (float64, s), ``seq`` (int64), ``acc_*``/``gyr_*`` (int64 counts), ``mag_*``
        (float64 counts, NaN on rows without a fresh sample), extra columns (float64) in file
        order. Row ``i`` is line ``i + 2`` of the file.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    RawDataError
        Empty file, missing or misspelled column, a line with the wrong number of cells (e.g. a
        truncated last line), a cell that is not a number (or not an integer count), an empty
        cell where a value is required, a magnetometer row with one or two of three cells, or a
        sensor column that is empty on every row.
    """
    path = _existing(path, "raw IMU recording (CSV)")
    names = _header_names(path, line=1, delimiter=",", expected=f"the header {_RAW_HEADER_TEXT}")
    _require_columns(
        path, 1, names, RAW_COLUMNS, f"the header {_RAW_HEADER_TEXT} (extra columns may follow)"
    )
    types = {name: pa.float64() for name in names if name != _TRAILING}
    types.update({SEQ: pa.int64(), **{c: pa.int64() for c in (*ACC, *GYR, *MAG)}})
    table = _read_delimited(path, names, types, delimiter=",", skip_rows=1, first_line=2)
    _check_presence(path, table, first_line=2, required=(TIME, SEQ, *ACC, *GYR), triple=MAG)
    return _to_frame(table, float_columns=MAG)


# --------------------------------------------------------------------------------------------
# MT Manager export (the reference)


def read_mt_manager_export(path: str | Path) -> MtManagerExport:
    """Read an Xsens MT Manager ASCII export (the reference IMU).

    Parameters
    ----------
    path : str or Path
        Text file: ``//`` comment lines (among them ``// Update Rate: 100.0Hz``), a
        tab-separated column header with ``PacketCounter``, optional ``SampleTimeFine``,
        ``Acc_X..Z`` (m/s^2), ``Gyr_X..Z`` (rad/s), ``Mag_X..Z`` (normalised), then data rows.

    Returns
    -------
    MtManagerExport

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    RawDataError
        As :func:`read_imu_csv`, and when neither ``SampleTimeFine`` nor the update rate is
        given (no way to know the time of a sample).
    """
    path = _existing(path, "reference recording (MT Manager export)")
    header: dict[str, str] = {}
    header_line = 0
    with path.open(encoding="utf-8-sig", errors="replace", newline=None) as f:
        for header_line, text in enumerate(f, start=1):
            if not text.startswith("//"):
                break
            key, sep, value = text[2:].partition(":")
            if sep:
                header[key.strip()] = value.strip()
        else:
            header_line += 1
    expected_header = "a tab-separated column header after the '//' lines"
    names = _header_names(path, line=header_line, delimiter="\t", expected=expected_header)
    _require_columns(
        path,
        header_line,
        names,
        _REF_REQUIRED,
        f"{expected_header} with {', '.join(_REF_REQUIRED)}",
    )
    update_rate_hz = _parse_update_rate(path, header)
    if REF_TIME_FINE not in names and update_rate_hz is None:
        raise RawDataError(
            path,
            header_line,
            f"no {REF_TIME_FINE} column and no '// Update Rate:' line",
            "one of them to know the sample times",
        )
    first_line = header_line + 1
    types = {name: pa.float64() for name in names if name != _TRAILING}
    types.update({REF_COUNTER: pa.int64(), REF_TIME_FINE: pa.int64()})
    types = {k: v for k, v in types.items() if k in names}
    table = _read_delimited(
        path, names, types, delimiter="\t", skip_rows=header_line, first_line=first_line
    )
    required = tuple(c for c in (REF_COUNTER, REF_TIME_FINE, *REF_ACC, *REF_GYR) if c in names)
    _check_presence(path, table, first_line=first_line, required=required, triple=REF_MAG)
    frame = _to_frame(table, float_columns=REF_MAG)
    return MtManagerExport(frame, header, update_rate_hz, first_line)


def _parse_update_rate(path: Path, header: Mapping[str, str]) -> float | None:
    text = header.get("Update Rate")
    if text is None:
        return None
    number = text.lower().removesuffix("hz").strip()
    try:
        rate = float(number)
    except ValueError:
        rate = float("nan")
    if not np.isfinite(rate) or rate <= 0:
        raise RawDataError(
            path,
            None,
            f"'// Update Rate: {text}' is not a rate",
            "a positive number of Hz such as '100.0Hz'",
        )
    return rate


# --------------------------------------------------------------------------------------------
# Shared reading machinery


def _existing(path: str | Path, what: str) -> Path:
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: {what} not found; expected an existing file")
    return path


def _header_names(path: Path, line: int, delimiter: str, expected: str) -> list[str]:
    """Column names on ``line`` (1-based); a trailing delimiter yields a placeholder name."""
    text = None
    with path.open(encoding="utf-8-sig", errors="replace", newline=None) as f:
        for number, text in enumerate(f, start=1):
            if number == line:
                break
        else:
            text = None
    if text is None or not text.strip():
        found = "the file is empty" if path.stat().st_size == 0 else "no column header"
        raise RawDataError(path, line if text is not None else None, found, expected)
    names = text.rstrip("\r\n").split(delimiter)
    if names and names[-1] == "" and len(names) > 1:
        names[-1] = _TRAILING
    seen: set[str] = set()
    for position, name in enumerate(names, start=1):
        if name == "" or name != name.strip():
            raise RawDataError(
                path,
                line,
                f"column {position} is named {name!r}",
                f"{expected} (names without spaces, none empty)",
            )
        if name in seen:
            raise RawDataError(path, line, f"column {name!r} appears twice", expected)
        seen.add(name)
    return names


def _require_columns(
    path: Path, line: int, names: list[str], required: tuple[str, ...], expected: str
) -> None:
    missing = [c for c in required if c not in names]
    if not missing:
        return
    others = [n for n in names if n not in required and n != _TRAILING]
    hints = []
    for name in missing:
        close = difflib.get_close_matches(name, others, n=1, cutoff=0.6)
        hints.append(f"{name!r} (found {close[0]!r} instead?)" if close else repr(name))
    noun = "column" if len(missing) == 1 else "columns"
    raise RawDataError(path, line, f"missing {noun} {', '.join(hints)}", expected)


def _read_delimited(
    path: Path,
    names: list[str],
    types: dict[str, pa.DataType],
    delimiter: str,
    skip_rows: int,
    first_line: int,
) -> pa.Table:
    """Read the data rows with pyarrow's CSV reader; on failure find the offending line."""
    read_options = pacsv.ReadOptions(column_names=names, skip_rows=skip_rows)
    # Blank lines are kept (as all-null rows) so that row i is line first_line + i.
    parse_options = pacsv.ParseOptions(
        delimiter=delimiter, quote_char=False, ignore_empty_lines=False
    )
    convert_options = pacsv.ConvertOptions(
        column_types=types,
        include_columns=[n for n in names if n != _TRAILING],
        null_values=[""],
        strings_can_be_null=False,
    )
    try:
        table = pacsv.read_csv(path, read_options, parse_options, convert_options)
    except pa.ArrowInvalid as err:
        _locate_bad_line(path, names, types, delimiter, first_line)
        raise RawDataError(
            path, None, f"unreadable ({err})", "the format of docs/data-format.md"
        ) from None
    if table.num_rows == 0:
        raise RawDataError(
            path, first_line, "no data rows after the header", "at least one row of samples"
        )
    _check_blank_lines(path, table, first_line)
    return table


def _locate_bad_line(
    path: Path, names: list[str], types: dict[str, pa.DataType], delimiter: str, first_line: int
) -> None:
    """Scan the file line by line for the problem pyarrow found and raise it (slow path)."""
    sep = "comma" if delimiter == "," else "tab"
    parsers: dict[str, Callable[[str], object]] = {
        name: (int if pa.types.is_integer(kind) else float) for name, kind in types.items()
    }
    with path.open(encoding="utf-8", errors="replace", newline=None) as f:
        for number, text in enumerate(f, start=1):
            if number < first_line:
                continue
            cells = text.rstrip("\n").split(delimiter)
            if cells == [""]:
                raise RawDataError(
                    path, number, "an empty line", "one row of samples per line (no blank lines)"
                )
            if len(cells) != len(names):
                # Universal newlines: only the last line of a file can lack its "\n".
                truncated = not text.endswith("\n") and len(cells) < len(names)
                found = (
                    f"the last line is truncated ({len(cells)} of {len(names)} cells)"
                    if truncated
                    else f"{len(cells)} {sep}-separated cells"
                )
                raise RawDataError(path, number, found, f"{len(names)} cells as in the header")
            for name, cell in zip(names, cells):
                parse = parsers.get(name)
                if parse is None or cell == "":
                    continue
                try:
                    parse(cell)
                except ValueError:
                    kind = "an integer raw count" if parse is int else "a number"
                    if name in (SEQ, REF_COUNTER, REF_TIME_FINE):
                        kind = "an integer counter"
                    found = f"column {name!r} holds {cell!r}"
                    raise RawDataError(path, number, found, kind) from None


def _check_blank_lines(path: Path, table: pa.Table, first_line: int) -> None:
    if table.column(0).null_count == 0:  # a blank line leaves every column null
        return
    all_null = None
    for column in table.columns:
        mask = column.is_null()
        all_null = mask if all_null is None else pc.and_(all_null, mask)
    if all_null is not None and pc.any(all_null).as_py():
        row = _first_true(all_null)
        raise RawDataError(
            path, first_line + row, "an empty line", "one row of samples per line (no blank lines)"
        )


def _check_presence(
    path: Path,
    table: pa.Table,
    first_line: int,
    required: tuple[str, ...],
    triple: tuple[str, str, str],
) -> None:
    """Required columns have a value on every row; the three ``triple`` cells go together."""
    n = table.num_rows
    last_line = first_line + n - 1
    for name in (*required, *triple):
        if table[name].null_count == n:
            raise RawDataError(
                path,
                None,
                f"column {name!r} is empty on every row (lines {first_line}-{last_line})",
                "values in it (a sensor that delivered no sample at all cannot be calibrated)",
            )
    for name in required:
        if table[name].null_count:
            row = _first_true(table[name].is_null())
            raise RawDataError(
                path, first_line + row, f"column {name!r} is empty", "a value on every row"
            )
    nulls = [table[c].is_null() for c in triple]
    some = pc.or_(pc.or_(nulls[0], nulls[1]), nulls[2])
    every = pc.and_(pc.and_(nulls[0], nulls[1]), nulls[2])
    partial = pc.and_(some, pc.invert(every))
    if pc.any(partial).as_py():
        row = _first_true(partial)
        empty = [c for c, m in zip(triple, nulls) if m[row].as_py()]
        raise RawDataError(
            path,
            first_line + row,
            f"{', '.join(empty)} empty but not the other {'/'.join(triple)} cells",
            "all three magnetometer cells filled (fresh sample) or all three empty",
        )


def _first_true(mask: pa.ChunkedArray | pa.Array) -> int:
    return int(np.flatnonzero(np.asarray(mask.to_numpy(zero_copy_only=False)))[0])


def _to_frame(table: pa.Table, float_columns: tuple[str, ...]) -> pd.DataFrame:
    """Columns to numpy without a pandas round trip per column type (fast, exact)."""
    data = {}
    for name in table.column_names:
        column = table[name]
        if name in float_columns:
            column = column.cast(pa.float64())
        data[name] = column.to_numpy()
    return pd.DataFrame(data, copy=False)
