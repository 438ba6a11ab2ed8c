"""The artifacts a lab report reads: JSON given as a path or already loaded, and the rules'
Snakemake benchmark files.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import pandas as pd

from imucal import io


def load_json(obj: Mapping | str | Path, what: str) -> dict:
    """A JSON artifact given as a path or as the loaded dict."""
    data = obj if isinstance(obj, Mapping) else io.read_json(obj)
    if not isinstance(data, Mapping):
        found = type(data).__name__
        raise ValueError(f"{what} is a JSON {found}; expected a JSON object")  # noqa: TRY004
    return dict(data)


def optional_json(obj: Mapping | str | Path | None, what: str) -> dict | None:
    return None if obj is None else load_json(obj, what)


def read_benchmarks(
    paths: Sequence[str | Path] | Mapping[str, str | Path], dataset: str
) -> pd.DataFrame:
    """Run time per rule from Snakemake benchmark TSV files.

    Parameters
    ----------
    paths : sequence of path, or mapping label -> path
        Benchmark files (columns ``s``, ``h:m:s``, ``max_rss`` (MB), ...; one row per repeat).
        Without labels, a file's label is its path below the folder named ``benchmarks``
        (a leading folder named like the dataset dropped), without ``.tsv``.
    dataset : str
        Dataset name (see above).

    Returns
    -------
    DataFrame
        Columns ``rule``, ``repeats``, ``s`` (mean wall time, s), ``max_rss_mb`` (max over
        repeats, MB; NaN where the file has none), sorted by ``s``, longest first.

    Raises
    ------
    ValueError
        If a file has no ``s`` column or no row.
    """
    items = paths.items() if isinstance(paths, Mapping) else ((None, p) for p in paths)
    rows = []
    for label, path in items:
        path = Path(path)
        table = pd.read_csv(path, sep="\t")
        if "s" not in table.columns or table.empty:
            raise ValueError(
                f"{path}: columns {list(table.columns)} and {len(table)} rows; expected a "
                "Snakemake benchmark file with an 's' column and at least one row"
            )
        rss = pd.to_numeric(table["max_rss"], errors="coerce") if "max_rss" in table else None
        rows.append(
            {
                "rule": label if label is not None else _benchmark_label(path, dataset),
                "repeats": len(table),
                "s": float(pd.to_numeric(table["s"]).mean()),
                "max_rss_mb": float(rss.max()) if rss is not None else float("nan"),
            }
        )
    frame = pd.DataFrame(rows, columns=["rule", "repeats", "s", "max_rss_mb"])
    return frame.sort_values("s", ascending=False, kind="stable").reset_index(drop=True)


def _benchmark_label(path: Path, dataset: str) -> str:
    parts = list(path.with_suffix("").parts)
    if "benchmarks" in parts:
        parts = parts[len(parts) - parts[::-1].index("benchmarks") :]
        if len(parts) > 1 and parts[0] == dataset:
            parts = parts[1:]
        return "/".join(parts)
    return path.stem
