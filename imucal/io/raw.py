"""Raw files of a session: the IMU CSV log and the MT Manager export, read with pyarrow.

The data contract is ``docs/data-format.md``. Readers check the *format* of a file (header,
cells, which cells may be empty) and report any problem as one :class:`RawDataError` naming
the file, the 1-based line number as a text editor shows it, and what was expected. Checks of
the *content* (time order, packet counter) live in :mod:`imucal.ingest`.

Both native formats are here because they share the reading machinery (header, pyarrow
options, locating the bad line, the cell checks), which the IMU CSV also runs batch by batch
(:class:`ImuCsvStream`).
"""

from __future__ import annotations

import difflib
import hashlib
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

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

#: Bytes of a raw log parsed per batch by :class:`ImuCsvStream`, about 300 000 rows of the IMU
#: CSV: one block of text is read, parsed on all cores (pyarrow's ``read_csv``) and handed on,
#: so the memory held is a few blocks whatever the length of the recording.
BATCH_BYTES = 1 << 24

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

    See Also
    --------
    ImuCsvStream : the same file in batches of bounded memory, with its SHA-256.
    """
    batches = list(ImuCsvStream(path))
    return _to_frame(pa.Table.from_batches(batches), float_columns=MAG)


class ImuCsvStream:
    """A raw IMU log in the native CSV format, read in batches of whole lines.

    Iterating yields the data rows as ``pyarrow.RecordBatch`` of raw counts in file order:
    ``t_s`` (float64, s), ``seq`` (int64), ``acc_*``/``gyr_*``/``mag_*`` (int64 counts, null
    where a magnetometer cell is empty), extra columns (float64). Row ``i`` of the file (counted
    over all batches) is line ``i + 2``. The format checks of :func:`read_imu_csv` are carried
    across batches, and the SHA-256 of the file's bytes is computed as they are read.

    Parameters
    ----------
    path : str or Path
        The CSV file.
    batch_bytes : int
        Bytes parsed per batch (:data:`BATCH_BYTES`); the memory held is a few batches.

    Attributes
    ----------
    path : Path
    names : list of str
        The header's column names.
    rows : int
        Data rows read so far.
    sha256 : str or None
        Hex SHA-256 of the whole file once the iteration has ended, else None.

    Raises
    ------
    FileNotFoundError, RawDataError
        As :func:`read_imu_csv`: header problems when created; problems of the rows when the
        iteration ends. The file is always read to its end before a row's problem is raised,
        so the error is the one :func:`read_imu_csv` reports for the whole file (a cell that
        cannot be read, then a blank line, a column empty on every row, an empty required
        cell, a partial magnetometer row), whatever the batch size. After the first problem no
        more batches are yielded.
    """

    def __init__(self, path: str | Path, batch_bytes: int = BATCH_BYTES) -> None:
        self.path = existing_file(path, "raw IMU recording (CSV)")
        self.batch_bytes = int(batch_bytes)
        self.names = _header_names(
            self.path, line=1, delimiter=",", expected=f"the header {_RAW_HEADER_TEXT}"
        )
        _require_columns(
            self.path,
            1,
            self.names,
            RAW_COLUMNS,
            f"the header {_RAW_HEADER_TEXT} (extra columns may follow)",
        )
        types = {name: pa.float64() for name in self.names if name != _TRAILING}
        types.update({SEQ: pa.int64(), **{c: pa.int64() for c in (*ACC, *GYR, *MAG)}})
        self.types = types
        self.rows = 0
        self.sha256: str | None = None

    @property
    def extra_columns(self) -> list[str]:
        """Columns after the required eleven (e.g. ``temp_c``), in file order."""
        return [n for n in self.names if n not in RAW_COLUMNS and n != _TRAILING]

    def __iter__(self) -> Iterator[pa.RecordBatch]:
        presence = _Presence(self.path, first_line=2, required=(TIME, SEQ, *ACC, *GYR), triple=MAG)
        self.rows = 0
        digest = hashlib.sha256()
        for batch in _read_delimited_batches(
            self.path,
            digest,
            self.names,
            self.types,
            delimiter=",",
            skip_rows=1,
            first_line=2,
            batch_bytes=self.batch_bytes,
        ):
            presence.update(batch, self.rows)
            self.rows += batch.num_rows
            if not presence.failed:
                yield batch
        if self.rows == 0:
            raise RawDataError(
                self.path, 2, "no data rows after the header", "at least one row of samples"
            )
        presence.finish(self.rows)
        self.sha256 = digest.hexdigest()


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
    path = existing_file(path, "reference recording (MT Manager export)")
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


def existing_file(path: str | Path, what: str) -> Path:
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


def _csv_options(
    names: list[str],
    types: dict[str, pa.DataType],
    delimiter: str,
    skip_rows: int,
) -> tuple[pacsv.ReadOptions, pacsv.ParseOptions, pacsv.ConvertOptions]:
    """pyarrow's CSV options of the native formats, for a whole read or one block of lines.

    Blank lines are kept (as all-null rows) so that row i is line ``first_line + i``.
    """
    return (
        pacsv.ReadOptions(column_names=names, skip_rows=skip_rows),
        pacsv.ParseOptions(delimiter=delimiter, quote_char=False, ignore_empty_lines=False),
        pacsv.ConvertOptions(
            column_types=types,
            include_columns=[n for n in names if n != _TRAILING],
            null_values=[""],
            strings_can_be_null=False,
        ),
    )


def _parse_delimited(
    source: Any,
    path: Path,
    names: list[str],
    types: dict[str, pa.DataType],
    delimiter: str,
    skip_rows: int,
    first_line: int,
) -> pa.Table:
    """``source`` (the file ``path`` or a block of its lines) parsed by pyarrow's CSV reader;
    when it cannot be, the offending line of the file is found and raised."""
    try:
        return pacsv.read_csv(source, *_csv_options(names, types, delimiter, skip_rows))
    except pa.ArrowInvalid as err:
        _locate_bad_line(path, names, types, delimiter, first_line)
        raise RawDataError(
            path, None, f"unreadable ({err})", "the format of docs/data-format.md"
        ) from None


def _read_delimited(
    path: Path,
    names: list[str],
    types: dict[str, pa.DataType],
    delimiter: str,
    skip_rows: int,
    first_line: int,
) -> pa.Table:
    """Read the data rows with pyarrow's CSV reader; on failure find the offending line."""
    table = _parse_delimited(path, path, names, types, delimiter, skip_rows, first_line)
    if table.num_rows == 0:
        raise RawDataError(
            path, first_line, "no data rows after the header", "at least one row of samples"
        )
    _check_blank_lines(path, table, first_line)
    return table


def _line_blocks(f: Any, block_bytes: int, digest: Any) -> Iterator[bytes | memoryview]:
    """The rest of the binary file ``f`` in blocks of whole lines, each byte added to ``digest``.

    A block is the next ``block_bytes`` read, up to its last newline, with the part line of the
    block before it in front; the last block may end without a newline. A line longer than a
    block is carried on until its newline, so no line is ever split.
    """
    rest = b""
    while data := f.read(block_bytes):
        digest.update(data)
        cut = data.rfind(b"\n") + 1
        if not cut:  # no line ends in this block
            rest += data
            continue
        yield rest + data[:cut] if rest else memoryview(data)[:cut]
        rest = data[cut:]
    if rest:
        yield rest


def _read_delimited_batches(
    path: Path,
    digest: Any,
    names: list[str],
    types: dict[str, pa.DataType],
    delimiter: str,
    skip_rows: int,
    first_line: int,
    batch_bytes: int,
) -> Iterator[pa.RecordBatch]:
    """:func:`_read_delimited` in batches, the SHA-256 of the whole file into ``digest``.

    The file is read in blocks of whole lines (:func:`_line_blocks`), each parsed by pyarrow's
    multithreaded ``read_csv`` into one batch: row ``i`` of the file is line ``first_line + i``
    as in a whole read (blank lines are all-null rows). A block that cannot be parsed is
    located in the file and raised.
    """
    with path.open("rb") as f:
        for _ in range(skip_rows):
            digest.update(f.readline())
        for block in _line_blocks(f, batch_bytes, digest):
            table = _parse_delimited(
                pa.py_buffer(block), path, names, types, delimiter, 0, first_line
            )
            if table.num_rows:
                yield from table.combine_chunks().to_batches()


class _Presence:
    """The cell checks of :func:`_check_presence` carried over batches, in the same order."""

    def __init__(
        self, path: Path, first_line: int, required: tuple[str, ...], triple: tuple[str, ...]
    ) -> None:
        self.path = path
        self.first_line = first_line
        self.required = required
        self.triple = triple
        self.blank: int | None = None
        self.filled = dict.fromkeys((*required, *triple), 0)
        self.first_empty: dict[str, int] = {}
        self.partial: tuple[int, list[str]] | None = None

    @property
    def failed(self) -> bool:
        """A problem was found (it is raised by :meth:`finish`, after the whole file)."""
        return self.blank is not None or bool(self.first_empty) or self.partial is not None

    def update(self, batch: pa.RecordBatch, start: int) -> None:
        """Check the rows ``start .. start + len(batch) - 1`` of the file."""
        if self.blank is None:
            row = _blank_row(batch)
            if row is not None:
                self.blank = start + row
        n = batch.num_rows
        for name in (*self.required, *self.triple):
            nulls = batch.column(name).null_count
            self.filled[name] += n - nulls
            if nulls and name in self.required and name not in self.first_empty:
                self.first_empty[name] = start + _first_true(batch.column(name).is_null())
        if self.partial is None:
            nulls = [batch.column(c).is_null() for c in self.triple]
            some = pc.or_(pc.or_(nulls[0], nulls[1]), nulls[2])
            every = pc.and_(pc.and_(nulls[0], nulls[1]), nulls[2])
            partial = pc.and_(some, pc.invert(every))
            if pc.any(partial).as_py():
                row = _first_true(partial)
                empty = [c for c, m in zip(self.triple, nulls) if m[row].as_py()]
                self.partial = (start + row, empty)

    def finish(self, rows: int) -> None:
        """Raise the first problem in the order of :func:`_check_presence`."""
        path, first_line = self.path, self.first_line
        if self.blank is not None:
            raise RawDataError(
                path,
                first_line + self.blank,
                "an empty line",
                "one row of samples per line (no blank lines)",
            )
        last_line = first_line + rows - 1
        for name in (*self.required, *self.triple):
            if self.filled[name] == 0:
                raise RawDataError(
                    path,
                    None,
                    f"column {name!r} is empty on every row (lines {first_line}-{last_line})",
                    "values in it (a sensor that delivered no sample at all cannot be calibrated)",
                )
        for name in self.required:
            if name in self.first_empty:
                raise RawDataError(
                    path,
                    first_line + self.first_empty[name],
                    f"column {name!r} is empty",
                    "a value on every row",
                )
        if self.partial is not None:
            row, empty = self.partial
            raise RawDataError(
                path,
                first_line + row,
                f"{', '.join(empty)} empty but not the other {'/'.join(self.triple)} cells",
                "all three magnetometer cells filled (fresh sample) or all three empty",
            )


def _blank_row(batch: pa.RecordBatch | pa.Table) -> int | None:
    """First row of ``batch`` whose every cell is null (a blank line), or None."""
    if batch.column(0).null_count == 0:
        return None
    all_null = None
    for column in batch.columns:
        mask = column.is_null()
        all_null = mask if all_null is None else pc.and_(all_null, mask)
    if all_null is not None and pc.any(all_null).as_py():
        return _first_true(all_null)
    return None


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
    row = _blank_row(table)
    if row is not None:
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
    presence = _Presence(path, first_line, required, triple)
    presence.update(table, 0)
    presence.finish(table.num_rows)


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
