"""Files the pipeline writes and reads back: parquet with metadata, JSON, CSV tables, calibration.

Writers are atomic: the data go to a temporary file beside the target, which is renamed over
the target only when complete, so no partial file is ever left under the target's name.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from collections.abc import Callable, Iterator, Mapping
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from imucal.columns import SEGMENT_COLUMNS, TIME
from imucal.io.raw import existing_file

if TYPE_CHECKING:  # the calibration (and its rotations: scipy.spatial) only where one is read
    from imucal.calibration import ImuCalibration

#: Key of the parquet key-value metadata that holds the JSON description of a recording.
METADATA_KEY = b"imucal"


# --------------------------------------------------------------------------------------------
# Checksums


def sha256_file(path: str | Path) -> str:
    """Return the hex SHA-256 of a file's bytes (records which raw file a result came from)."""
    digest = hashlib.sha256()
    with existing_file(path, "file").open("rb") as f:
        for block in iter(lambda: f.read(1 << 22), b""):
            digest.update(block)
    return digest.hexdigest()


# --------------------------------------------------------------------------------------------
# Parquet with metadata


def _dictionary_columns(schema: pa.Schema) -> list[str]:
    """Columns parquet encodes with a dictionary: all but the time, whose values are unique
    per row (a dictionary there is tried, overflows and falls back, which only costs time);
    quantised sensor values, the packet counter and a temperature have few distinct values."""
    return [name for name in schema.names if name != TIME]


def write_recording(table: pd.DataFrame, path: str | Path, metadata: Mapping[str, Any]) -> None:
    """Write an ingested recording to parquet, atomically, with its JSON metadata.

    Parameters
    ----------
    table : DataFrame, shape (n, k)
        Ingested columns (see ``docs/architecture.md``).
    path : str or Path
        Target ``.parquet`` file; its folder is created.
    metadata : mapping
        JSON-serialisable description, stored as parquet key-value metadata ``imucal``.
    """
    arrow = pa.Table.from_pandas(table, preserve_index=False)
    arrow = arrow.replace_schema_metadata(
        {**(arrow.schema.metadata or {}), METADATA_KEY: _metadata_blob(metadata)}
    )
    dictionary = _dictionary_columns(arrow.schema)
    _write_atomic(path, lambda tmp: pq.write_table(arrow, tmp, use_dictionary=dictionary))


class RecordingWriter:
    """Write an ingested recording batch by batch, as parquet row groups, atomically.

    The file reads back exactly as one written by :func:`write_recording` from the whole
    table: same columns and types, nulls where the table has NaN, the same ``pandas`` and
    ``imucal`` schema metadata. The metadata is known only at the end (the SHA-256 of a raw
    file is computed as it is read), so it goes into the parquet footer as key-value metadata,
    which is where :func:`read_recording` finds it; no ``ARROW:schema`` copy of the schema is
    stored (every column is a plain float64 or int64).

    Use as a context manager: the rows go to a temporary file beside ``path``, which is renamed
    to ``path`` by :meth:`close`; leaving the ``with`` block without calling it (an exception)
    removes the temporary file, so no partial file is ever left under the target's name.

    A batch is encoded and written in a background thread while the caller prepares the next
    one (pyarrow releases the GIL), so reading and writing overlap; at most one batch is in
    flight, and an error of the write is raised by the next :meth:`write` or :meth:`close`.

    Parameters
    ----------
    path : str or Path
        Target ``.parquet`` file; its folder is created.
    dtypes : mapping
        Column name -> numpy dtype (``float64`` or ``int64``), in column order.
    """

    def __init__(self, path: str | Path, dtypes: Mapping[str, Any]) -> None:
        self.path = Path(path)
        self.rows = 0
        empty = pd.DataFrame({name: np.empty(0, dtype=kind) for name, kind in dtypes.items()})
        schema = pa.Schema.from_pandas(empty, preserve_index=False)
        self._pandas = (schema.metadata or {}).get(b"pandas")
        self.schema = schema.remove_metadata()
        self._tmp = ""
        self._writer: pq.ParquetWriter | None = None
        self._thread = ThreadPoolExecutor(max_workers=1, thread_name_prefix="parquet-writer")
        self._pending: Future | None = None

    def __enter__(self) -> RecordingWriter:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._tmp = _temporary_beside(self.path)
        try:
            self._writer = pq.ParquetWriter(
                self._tmp,
                self.schema,
                store_schema=False,
                use_dictionary=_dictionary_columns(self.schema),
            )
        except BaseException:
            self._thread.shutdown()
            Path(self._tmp).unlink(missing_ok=True)
            raise
        return self

    def write(self, columns: Mapping[str, np.ndarray | pa.Array]) -> None:
        """Append rows: one array per column of ``dtypes``, equal lengths; NaN becomes null."""
        arrays = [
            pa.array(columns[field.name], type=field.type, from_pandas=True)
            if isinstance(columns[field.name], np.ndarray)
            else columns[field.name]
            for field in self.schema
        ]
        batch = pa.RecordBatch.from_arrays(arrays, schema=self.schema)
        self._wait()
        self._pending = self._thread.submit(self._writer.write_batch, batch)
        self.rows += batch.num_rows

    def close(self, metadata: Mapping[str, Any]) -> None:
        """Store ``metadata`` (as :func:`write_recording` does) and move the file in place."""
        self._wait()
        keys = {METADATA_KEY: _metadata_blob(metadata)}
        if self._pandas is not None:
            keys = {b"pandas": self._pandas, **keys}
        self._writer.add_key_value_metadata(keys)
        self._writer.close()
        os.replace(self._tmp, self.path)

    def _wait(self) -> None:
        """Wait for the batch in flight; raise its error."""
        pending, self._pending = self._pending, None
        if pending is not None:
            pending.result()

    def __exit__(self, kind: object, error: object, trace: object) -> None:
        self._thread.shutdown(wait=True)
        if kind is not None or Path(self._tmp).exists():
            if self._writer is not None and self._writer.is_open:
                self._writer.close()
            Path(self._tmp).unlink(missing_ok=True)


def _metadata_blob(metadata: Mapping[str, Any]) -> bytes:
    return json.dumps(to_jsonable(metadata), sort_keys=True).encode()


def read_recording(path: str | Path) -> tuple[pd.DataFrame, dict]:
    """Read an ingested recording.

    Returns
    -------
    table : DataFrame, shape (n, k)
    metadata : dict
        The ``imucal`` metadata (dataset, recording, source, sha256, sensitivity, units, ...).

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        If the file carries no ``imucal`` metadata (not written by :func:`write_recording`).
    """
    path = existing_file(path, "ingested recording (parquet)")
    arrow = pq.read_table(path)
    blob = (arrow.schema.metadata or {}).get(METADATA_KEY)
    if blob is None:
        raise ValueError(
            f"{path}: no 'imucal' parquet metadata; expected a recording written "
            "by imucal.io.write_recording"
        )
    return arrow.to_pandas(), json.loads(blob)


def recording_column_names(path: str | Path) -> list[str]:
    """Column names of an ingested recording, read from the parquet schema alone."""
    return list(pq.read_schema(existing_file(path, "ingested recording (parquet)")).names)


def read_recording_batches(
    path: str | Path, batch_rows: int = 100_000
) -> tuple[int, Iterator[pd.DataFrame]]:
    """An ingested recording in consecutive row batches, so that a long one is never held whole.

    Parameters
    ----------
    path : str or Path
    batch_rows : int
        Largest number of rows of a batch (a batch may be shorter at a row-group boundary).

    Returns
    -------
    n_rows : int
        Rows of the whole recording (from the parquet metadata).
    batches : iterator of DataFrame
        The rows in file order, every column.
    """
    path = existing_file(path, "ingested recording (parquet)")
    file = pq.ParquetFile(path)
    batches = (b.to_pandas() for b in file.iter_batches(batch_size=batch_rows))
    return file.metadata.num_rows, batches


def read_recording_column(path: str | Path, column: str) -> np.ndarray:
    """One column of an ingested recording as float64, shape (n,) (the others stay on disk).

    Raises
    ------
    ValueError
        If the recording has no column ``column``.
    """
    path = existing_file(path, "ingested recording (parquet)")
    names = pq.read_schema(path).names
    if column not in names:
        raise ValueError(f"{path}: no column {column!r}; it has {names}")
    values = pq.read_table(path, columns=[column]).column(0)
    return values.to_numpy().astype(float, copy=False)


def read_segments(path: str | Path) -> pd.DataFrame:
    """Read the segments table (``results/{dataset}/segments.parquet``).

    Returns
    -------
    DataFrame, shape (m, 11)
        The columns of :data:`imucal.columns.SEGMENT_COLUMNS` (``docs/architecture.md``);
        ``attrs`` ``notes`` and ``held_by_hand`` as :func:`imucal.segments.segmentation.segment_dataset`
        gave them (empty for a table written without them).

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        If it lacks ``imucal`` metadata or a segments column.
    """
    table, metadata = read_recording(path)
    missing = [c for c in SEGMENT_COLUMNS if c not in table.columns]
    if missing:
        raise ValueError(
            f"{path}: segments table lacks the columns {missing}; expected {SEGMENT_COLUMNS}"
        )
    table.attrs["notes"] = dict(metadata.get("notes", {}))
    table.attrs["held_by_hand"] = list(metadata.get("held_by_hand", []))
    return table


def write_table(table: pd.DataFrame, path: str | Path) -> None:
    """Write a small result table (e.g. the paper's Tables I and II) as CSV, atomically.

    Parameters
    ----------
    table : DataFrame, shape (m, k)
        Written without its index, comma-separated, floats in round-trip precision.
    path : str or Path
        Target ``.csv`` file; its folder is created.
    """
    _write_atomic(path, lambda tmp: table.to_csv(tmp, index=False, lineterminator="\n"))


def read_benchmark_seconds(paths: list[str | Path]) -> dict:
    """Wall-clock time of the jobs of Snakemake benchmark files (column ``s``, seconds).

    Parameters
    ----------
    paths : list of str or Path
        Benchmark TSV files, one job each (the first row is read).

    Returns
    -------
    dict
        ``median`` and ``max`` over the files, s.

    Raises
    ------
    ValueError
        If ``paths`` is empty.
    """
    if not paths:
        raise ValueError("no benchmark files; expected at least one")
    seconds = [
        float(pd.read_csv(existing_file(p, "benchmark"), sep="\t")["s"].iloc[0]) for p in paths
    ]
    return {"median": float(np.median(seconds)), "max": max(seconds)}


# --------------------------------------------------------------------------------------------
# JSON and calibration files


def write_json(obj: Any, path: str | Path) -> None:
    """Write ``obj`` as indented JSON, atomically (numpy values become plain numbers)."""
    text = json.dumps(to_jsonable(obj), indent=2, sort_keys=False, allow_nan=False) + "\n"
    _write_atomic(path, lambda tmp: Path(tmp).write_text(text))


def read_json(path: str | Path) -> Any:
    """Read a JSON file.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        If it is not valid JSON; the message names the line.
    """
    path = existing_file(path, "JSON file")
    try:
        return json.loads(path.read_text())
    except json.JSONDecodeError as err:
        raise ValueError(
            f"{path}, line {err.lineno}: not valid JSON ({err.msg}); expected a JSON document"
        ) from None


def write_calibration(calibration: ImuCalibration, path: str | Path) -> None:
    """Write ``calibration.to_dict()`` (versioned, with units) as JSON, atomically."""
    write_json(calibration.to_dict(), path)


def read_calibration(path: str | Path) -> ImuCalibration:
    """Read a calibration file written by :func:`write_calibration`.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        If the file is newer than this package (``format_version``), is for another unit, or
        lacks a key; the message names the file.
    """
    from imucal.calibration import ImuCalibration

    data = read_json(path)
    if not isinstance(data, dict):
        raise ValueError(f"{path}: top level is {type(data).__name__}; expected a JSON object")  # noqa: TRY004
    try:
        return ImuCalibration.from_dict(data)
    except ValueError as err:
        raise ValueError(f"{path}: {err}") from None


# --------------------------------------------------------------------------------------------
# Helpers and the JSON converter


def _write_atomic(path: str | Path, write: Callable[[str], object]) -> None:
    """Call ``write(tmp)`` on a temporary file beside ``path``, then rename it to ``path``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = _temporary_beside(path)
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _temporary_beside(path: Path) -> str:
    """An empty temporary file in ``path``'s folder with the permissions a new file gets there.

    ``tempfile.mkstemp`` creates it readable by its owner alone; the renamed artifact would keep
    that mode, so it is set to what ``open`` would give (``0o666`` less the process's umask).
    """
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    umask = os.umask(0)
    os.umask(umask)
    os.fchmod(fd, 0o666 & ~umask)
    os.close(fd)
    return tmp


def to_jsonable(obj: Any) -> Any:
    """Plain JSON types: numpy scalars and arrays to numbers and lists, NaN and inf to None.

    The package's one converter: every JSON file and parquet metadata blob goes through it.
    """
    if isinstance(obj, Mapping):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple, np.ndarray)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, (np.integer, np.bool_)):
        return obj.item()
    if isinstance(obj, (float, np.floating)):
        value = float(obj)
        return value if np.isfinite(value) else None
    if isinstance(obj, Path):
        return str(obj)
    return obj
