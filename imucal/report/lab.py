"""HTML lab report of one dataset: collect the artifacts into a context, render it (jinja2).

The report is one self-contained file: figures are embedded as base64 data URIs, the CSS is
inline, there is no script and a Content-Security-Policy forbids loading anything that is not in
the file, so it reads the same offline. :func:`build_report_context` takes every artifact
explicitly (paths or already-loaded objects; the rule script passes ``snakemake.input``, this
module never globs) and formats all numbers; :func:`render_report` only lays them out with the
template ``imucal/report/templates/report.html.j2``.

The module is long (about 860 lines): it turns every artifact of a run into the report's
context; the sections share the formatting helpers, so they stay in one place.
"""

from __future__ import annotations

import base64
import datetime as _dt
import json
import math
import os
import re
from collections.abc import Mapping, Sequence
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any

import jinja2
import numpy as np
import pandas as pd
import yaml

import imucal
from imucal import io
from imucal.columns import AXES, SENSORS
from imucal.constants import REFERENCE
from imucal.pipeline.outcome import NOT_SHIPPED
from imucal.report import digest
from imucal.report.holdout import holdout_section
from imucal.report.numbers import format_number, format_value
from imucal.terms.comparison import gap_comparison

#: Section of the report for each sensor, in report order.
SENSOR_SECTIONS = {"mag": "magnetometer", "acc": "accelerometer", "gyr": "gyroscope"}
SECTION_TITLES = {
    "segmentation": "Segmentation",
    "magnetometer": "Magnetometer",
    "accelerometer": "Accelerometer",
    "gyroscope": "Gyroscope",
    "validation": "Validation against the reference",
    "other": "Other figures",
}
#: First word of a figure's file name (before '_' or '-') -> report section. A figure in a
#: folder named ``segments`` belongs to the segmentation whatever its name.
FIGURE_SECTION_BY_PREFIX = {
    "seg": "segmentation",
    "segment": "segmentation",
    "segments": "segmentation",
    "segmentation": "segmentation",
    "mag": "magnetometer",
    "magnetometer": "magnetometer",
    "acc": "accelerometer",
    "accelerometer": "accelerometer",
    "cube": "accelerometer",
    "gyr": "gyroscope",
    "gyro": "gyroscope",
    "gyroscope": "gyroscope",
    "ratetable": "gyroscope",
    "validation": "validation",
    "reference": "validation",
}
#: Default captions of the figures the stage rules are expected to write (file stem -> text).
#: Any other figure gets a caption made from its file name unless one is passed in.
DEFAULT_CAPTIONS = {
    "mag_raw": "Magnetometer readings before calibration (paper Fig. 4).",
    "mag_step1": "Magnetometer after step 1, the ellipsoid fit (paper Fig. 5).",
    "mag_phases": "Magnetometer phases x, y, z with the extreme points used by eqs. 25-27 "
    "(paper Fig. 6).",
    "mag_step2": "Magnetometer after step 2, the alignment T_R (paper Fig. 7).",
    "acc_cube": "Accelerometer |a| - g per cube position before and after the cube fit "
    "(paper Fig. 10).",
    "acc_phases": "Low-pass filtered accelerometer phases before and after alignment "
    "(paper Figs. 11-13).",
    "gyr_bias": "Gyroscope before and after bias removal (paper Figs. 16-17).",
    "gyr_phases": "Gyroscope phases before and after alignment (paper Figs. 18-19).",
    "gyr_table": "Rate-table magnitude errors |w| - |w_true| per run before and after "
    "calibration (paper Fig. 15).",
    "validation": "Magnitudes of the calibrated module and of the reference (paper Fig. 20).",
    "validation_magnitudes": "Magnitudes of the calibrated module and of the reference after "
    "time alignment and mounting (paper Fig. 20).",
    "validation_xcorr": "Cross-correlation of the rate magnitudes of module and reference: its "
    "peak gives the time offset of the reference's clock.",
    "reference_orientation": "Orientation error integrated from the gyroscope against the "
    "declared orientation reference, raw, with the bias only and calibrated.",
    "noise_allan": "Allan deviation per axis with confidence bars and the fitted noise model.",
}
#: Titles and units of the paper's tables in ``tables.csv`` (key: the ``table`` column).
TABLE_TITLES = {
    "I": ("Table I: gyroscope bias", "rad/s"),
    "II": ("Table II: gyroscope scale", "1"),
}
#: Units of the calibration parameters other than the bias (which is in the sensor's unit).
PARAMETER_UNITS = {"scale": "1", "xi_rad": "rad", "alpha_rad": "rad"}
PARAMETER_NAMES = {
    "bias": "bias o",
    "scale": "scale s",
    "xi_rad": "non-orthogonality ξ",
    "alpha_rad": "misalignment α",
}
_MIME = {".png": "image/png", ".svg": "image/svg+xml"}
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: Name of the rate-table recording (one of imucal.io.dataset.RECORDING_NAMES).
RATE_TABLE = "ratetable"
# Sentence shown when the ingest summary has no such recording.
_RECORDING_ABSENT = {
    REFERENCE: "The dataset has no reference recording, so the calibrated module is not "
    "compared with a reference (no paper Fig. 20).",
    RATE_TABLE: "The dataset has no rate-table recording, so there are no rate-table "
    "magnitude errors (no paper Fig. 15); the gyroscope's method says how it was calibrated "
    "without one.",
}


# --------------------------------------------------------------------------------------------
# Formatting


def _is_scalar(value: Any) -> bool:
    return value is None or isinstance(value, (str, bool, int, float, np.number, np.bool_))


def _with_std(value: Any, std: Any) -> str:
    """``value ± std`` (std with 2 significant digits), or the value alone if std is unknown."""
    if std is not None and float(std) == 0.0:
        return f"{format_number(value)} (fixed, not observable)"
    if std is None or not math.isfinite(float(std)):
        return format_number(value)
    return f"{format_number(value)} ± {format_number(std, 2)}"


# --------------------------------------------------------------------------------------------
# Loading


def _load_json(obj: Mapping | str | Path, what: str) -> dict:
    """A JSON artifact given as a path or as the loaded dict."""
    data = obj if isinstance(obj, Mapping) else io.read_json(obj)
    if not isinstance(data, Mapping):
        found = type(data).__name__
        raise ValueError(f"{what} is a JSON {found}; expected a JSON object")  # noqa: TRY004
    return dict(data)


def _optional_json(obj: Mapping | str | Path | None, what: str) -> dict | None:
    return None if obj is None else _load_json(obj, what)


def embed_figure(path: str | Path) -> str:
    """Return a ``data:`` URI with the PNG or SVG file at ``path`` base64-encoded.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        If the file is neither ``.png`` nor ``.svg``, or a ``.png`` lacks the PNG signature.
    """
    path = Path(path)
    mime = _MIME.get(path.suffix.lower())
    if mime is None:
        raise ValueError(
            f"figure {path} has suffix {path.suffix!r}; expected one of {sorted(_MIME)}"
        )
    if not path.is_file():
        raise FileNotFoundError(f"{path}: figure not found; expected an existing file")
    data = path.read_bytes()
    if mime == "image/png" and not data.startswith(_PNG_SIGNATURE):
        raise ValueError(f"figure {path} does not start with the PNG signature; expected a PNG")
    return f"data:{mime};base64,{base64.b64encode(data).decode('ascii')}"


def figure_section(path: str | Path) -> str:
    """Report section of a figure from its folder and file name (see FIGURE_SECTION_BY_PREFIX)."""
    path = Path(path)
    if path.parent.name == "segments":
        return "segmentation"
    prefix = re.split(r"[_\-.]", path.stem.lower(), maxsplit=1)[0]
    return FIGURE_SECTION_BY_PREFIX.get(prefix, "other")


def _caption(path: Path, captions: Mapping[str, str]) -> str:
    stem = path.stem
    if stem in captions:
        return captions[stem]
    if stem in DEFAULT_CAPTIONS:
        return DEFAULT_CAPTIONS[stem]
    words = re.sub(r"[_\-]+", " ", stem).strip()
    if path.parent.name == "segments":
        return f"Segments found in the {words} recording."
    return f"{words[:1].upper()}{words[1:]}."


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


# --------------------------------------------------------------------------------------------
# Generic rendering of nested JSON


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


# --------------------------------------------------------------------------------------------
# Sections


def _session(summary: Mapping, declared_reference: bool = False) -> dict:
    recordings = summary.get("recordings", {})
    rows, gaps = [], []
    for name, rec in recordings.items():
        lost_fraction = rec.get("lost_fraction")
        rows.append(
            {
                "recording": name,
                "file": Path(rec["source"]).name if rec.get("source") else "n/a",
                "source": rec.get("source") or "n/a",
                "format": rec.get("format") or "n/a",
                "sha256": rec.get("sha256") or "n/a",
                "rows": format_number(rec.get("rows")),
                "duration_s": format_number(rec.get("duration_s")),
                "rate_hz": format_number(rec.get("rate_hz")),
                "received_rate_hz": format_number(rec.get("received_rate_hz")),
                "mag_rate_hz": format_number(rec.get("mag_rate_hz")),
                "lost_packets": format_number(rec.get("lost_packets")),
                "lost_pct": format_number(
                    None if lost_fraction is None else 100 * lost_fraction, 3
                ),
                "n_gaps": format_number(rec.get("n_gaps")),
                "duplicated_rows": format_number(rec.get("duplicated_rows")),
                "out_of_order_rows": format_number(rec.get("out_of_order_rows")),
                "flag": bool(
                    rec.get("lost_packets")
                    or rec.get("duplicated_rows")
                    or rec.get("out_of_order_rows")
                ),
            }
        )
        listed = rec.get("gaps") or []
        if listed:
            gaps.append(
                {
                    "recording": name,
                    "n_gaps": int(rec.get("n_gaps", len(listed))),
                    "n_listed": len(listed),
                    "rows": [
                        {
                            "line": format_number(g.get("line")),
                            "t_s": format_number(g.get("t_s"), 6),
                            "dt_s": format_number(g.get("dt_s"), 3),
                            "seq_before": format_number(g.get("seq_before")),
                            "seq": format_number(g.get("seq")),
                            "lost": format_number(g.get("lost")),
                        }
                        for g in listed
                    ],
                }
            )
    durations = [
        rec.get("duration_s") or 0.0 for name, rec in recordings.items() if name != REFERENCE
    ]
    absent = {name for name in _RECORDING_ABSENT if name not in recordings}
    if declared_reference:
        absent.discard(REFERENCE)  # a reference declared with a recording (dataset.yaml)
    notes = [text for name, text in _RECORDING_ABSENT.items() if name in absent]
    return {
        "recordings": rows,
        "gaps": gaps,
        "n_imu_recordings": len(durations),
        "imu_duration_s": format_number(sum(durations)),
        "total_lost_packets": format_number(
            summary.get(
                "lost_packets", sum(r.get("lost_packets") or 0 for r in recordings.values())
            )
        ),
        "notes": notes,
    }


def _sensor_parameters(sensor: str, cal: Mapping) -> dict:
    """Parameter rows (x, y, z with ± std) and the matrix of one sensor of calibration.json."""
    std = cal.get("std") or {}
    unit = cal.get("unit_in", "")
    rows = []
    for key in ("bias", "scale", "xi_rad", "alpha_rad"):
        if key not in cal:
            continue
        unit_of = unit if key == "bias" else PARAMETER_UNITS[key]
        sd = std.get(key)
        rows.append(
            {
                "name": PARAMETER_NAMES[key],
                "unit": unit_of,
                "cells": [
                    _with_std(v, None if sd is None else sd[i]) for i, v in enumerate(cal[key])
                ],
            }
        )
    sd_matrix = std.get("matrix")
    matrix = [
        [_with_std(v, None if sd_matrix is None else sd_matrix[i][j]) for j, v in enumerate(row)]
        for i, row in enumerate(cal["matrix"])
    ]
    unknown_std = [
        PARAMETER_NAMES.get(k, k)
        for k in ("bias", "matrix", "scale", "xi_rad", "alpha_rad")
        if k not in std
    ]
    return {
        "sensor": sensor,
        "unit_in": unit,
        "unit_out": cal.get("unit_out", unit),
        "method": cal.get("method") or "not stated",
        "rows": rows,
        "matrix": matrix,
        "std_unknown": unknown_std,
        "quality": _quality_rows(cal.get("quality") or {}),
        "has_covariance": cal.get("covariance") is not None,
    }


def _quality_rows(quality: Mapping) -> list[dict]:
    """Per stage behind a calibration: chi-square / dof, inflation and the rule stated."""
    rows = []
    for stage, q in quality.items():
        ratio = q.get("chi2_per_dof")
        inflation = q.get("inflation")
        rows.append(
            {
                "stage": stage,
                "chi2": "" if ratio is None else f"{format_number(q['chi2'], 3)} / {q['dof']}",
                "ratio": "" if ratio is None else format_number(ratio, 3),
                "inflated": (
                    ""
                    if inflation is None
                    else (
                        f"yes: covariance x {format_number(inflation, 3)}"
                        if inflation > 1
                        else "no"
                    )
                ),
                "rule": q.get("rule", ""),
                "crlb": (
                    "" if q.get("std_over_crlb") is None else format_number(q["std_over_crlb"], 3)
                ),
            }
        )
    return rows


def _paper_tables(tables: pd.DataFrame | None) -> list[dict]:
    if tables is None:
        return []
    missing = {"table", "row", *AXES} - set(tables.columns)
    if missing:
        raise ValueError(
            f"tables.csv has columns {list(tables.columns)}; expected table, row, x, y, z "
            f"(missing {sorted(missing)})"
        )
    out = []
    for name, group in tables.groupby("table", sort=False):
        key = re.sub(r"^table\s+", "", str(name), flags=re.IGNORECASE)
        title, unit = TABLE_TITLES.get(key, (f"Table {key}", None))
        if "unit" in group.columns and group["unit"].notna().any():
            unit = str(group["unit"].dropna().iloc[0])
        rows = [
            {"row": str(r["row"]), "cells": [format_number(r[a]) for a in AXES]}
            for _, r in group.iterrows()
        ]
        has_truth = any(r["row"].strip().lower() == "truth" for r in rows)
        out.append({"title": title, "unit": unit, "rows": rows, "has_truth": has_truth})
    return out


# --------------------------------------------------------------------------------------------
# Public API


def build_report_context(
    *,
    dataset: str,
    summary: Mapping | str | Path,
    calibration: Mapping | str | Path,
    mag_result: Mapping | str | Path | None = None,
    acc_result: Mapping | str | Path | None = None,
    gyr_result: Mapping | str | Path | None = None,
    validation: Mapping | str | Path | None = None,
    tables: pd.DataFrame | str | Path | None = None,
    stages: Mapping | str | Path | None = None,
    figures: Sequence[str | Path] = (),
    captions: Mapping[str, str] | None = None,
    benchmarks: Sequence[str | Path] | Mapping[str, str | Path] = (),
    config: Mapping | None = None,
    git_commit: str = "unknown",
    snakemake_version: str | None = None,
    imucal_version: str | None = None,
    generated: str | None = None,
    gap: Sequence[str | Path] | None = None,
    noise: Sequence[str | Path] | None = None,
    terms: Sequence[str | Path] | None = None,
    report_path: str | Path | None = None,
    temperature_holdout: str | Path | None = None,
) -> dict:
    """Collect the artifacts of one dataset into the context of the report template.

    Parameters
    ----------
    dataset : str
        Dataset name.
    summary : mapping or path
        ``results/{dataset}/ingest/summary.json`` (:func:`imucal.ingest.summarize_dataset`).
    calibration : mapping or path
        ``results/{dataset}/calibration.json`` (:meth:`imucal.ImuCalibration.to_dict`); a partial
        session's calibration may lack sensors it names in ``missing`` (sensor -> reason).
    stages : mapping or path, optional
        ``results/{dataset}/stages.json``: ``stages``, a list of {stage, what, status, reason}.
    mag_result, acc_result, gyr_result : mapping or path, optional
        The per-stage JSONs (``mag.json``, ``acc.json``, ``gyr.json``); rendered generically.
    validation : mapping or path, optional
        ``validation.json``, a nested dict of metrics; None when there is no reference.
    tables : DataFrame or path, optional
        ``tables.csv`` with columns ``table``, ``row``, ``x``, ``y``, ``z`` (optional ``unit``).
    figures : sequence of path
        PNG (or SVG) files; each is embedded once, in the section given by
        :func:`figure_section`, in the order given.
    captions : mapping, optional
        File stem -> caption; overrides :data:`DEFAULT_CAPTIONS`.
    benchmarks : sequence of path or mapping label -> path
        Snakemake benchmark TSV files (:func:`read_benchmarks`).
    config : mapping, optional
        The settings of the run (the dataset's folder and config sections), shown in the
        provenance.
    git_commit : str
        Commit of the workflow ("unknown" when not in a git checkout).
    snakemake_version : str, optional
        Default: the version of the installed ``snakemake`` distribution, or "unknown".
    imucal_version : str, optional
        Package version; default :data:`imucal.__version__`.
    generated : str, optional
        Time stamp of the report; default now (UTC, ISO 8601, seconds).
    report_path : path, optional
        Where the report will be written: the stage results given as paths are linked from it
        by their path relative to its folder (none linked without it).
    temperature_holdout : path, optional
        ``temperature_holdout.json`` (:mod:`imucal.report.holdout`), its own section.

    Returns
    -------
    dict
        Everything :func:`render_report` needs, numbers already formatted as strings.

    Raises
    ------
    FileNotFoundError
        If a given file does not exist.
    ValueError
        If an artifact has the wrong form (see the loaders).
    """
    summary = _load_json(summary, "ingest summary")
    calibration = _load_json(calibration, "calibration")
    not_calibrated = dict(calibration.get("missing", {}))
    missing = [s for s in SENSORS if s not in calibration and s not in not_calibrated]
    if missing:
        raise ValueError(
            f"calibration lacks the sensors {missing} and gives no reason for them in 'missing'; "
            "expected acc, gyr and mag"
        )
    stages = _optional_json(stages, "stages.json")
    links = {
        name: _link(obj, report_path)
        for name, obj in (
            ("mag", mag_result),
            ("acc", acc_result),
            ("gyr", gyr_result),
            ("validation", validation),
        )  # fmt: skip
    }
    results = {
        "mag": _optional_json(mag_result, "mag.json"),
        "acc": _optional_json(acc_result, "acc.json"),
        "gyr": _optional_json(gyr_result, "gyr.json"),
    }
    validation = _optional_json(validation, "validation.json")
    if tables is not None and not isinstance(tables, pd.DataFrame):
        tables = pd.read_csv(tables)
    captions = dict(captions or {})

    # Grouped by section (in report order), then numbered as they appear in the report.
    figure_items: dict[str, list[dict]] = {name: [] for name in SECTION_TITLES}
    for path in map(Path, figures):
        figure_items[figure_section(path)].append(
            {"src": embed_figure(path), "caption": _caption(path, captions), "file": path.name}
        )
    for number, item in enumerate(
        (item for items in figure_items.values() for item in items), start=1
    ):
        item["number"] = number

    warnings: list[dict] = []
    for sensor, result in results.items():
        if result is not None:
            warnings += collect_warnings(result, f"{sensor}.json")
    if validation is not None:
        warnings += collect_warnings(validation, "validation.json")
    # a stage whose fit was refused (the simpler one's calibration is shipped) says why here too
    warnings += [
        {"source": "stages.json", "where": row["stage"], "text": row["reason"]}
        for row in (stages or {}).get("stages", [])
        if str(row.get("reason", "")).startswith(NOT_SHIPPED)
    ]

    recordings = summary.get("recordings", {})
    sensors = []
    for sensor, section in SENSOR_SECTIONS.items():
        result = results[sensor]
        if sensor in not_calibrated:
            sensors.append(
                {
                    "id": section,
                    "title": SECTION_TITLES[section],
                    "parameters": None,
                    "result_file": f"{sensor}.json",
                    "result": None,
                    "tables": [],
                    "link": links[sensor],
                    "figures": figure_items[section],
                    "notes": [f"Not calibrated: {not_calibrated[sensor]}"],
                }
            )
            continue
        sensors.append(
            {
                "id": section,
                "title": SECTION_TITLES[section],
                "parameters": _sensor_parameters(sensor, calibration[sensor]),
                "result_file": f"{sensor}.json",
                "result": None if result is None else flatten_fields(result),
                "tables": digest.stage_tables(sensor, result),
                "link": links[sensor],
                "figures": figure_items[section],
                "notes": (
                    [_RECORDING_ABSENT[RATE_TABLE]]
                    if sensor == "gyr" and RATE_TABLE not in recordings
                    else []
                ),
            }
        )

    bench = read_benchmarks(benchmarks, dataset)
    if snakemake_version is None:
        try:
            snakemake_version = version("snakemake")
        except PackageNotFoundError:
            snakemake_version = "unknown"
    if imucal_version is None:
        imucal_version = imucal.__version__
    if generated is None:
        generated = _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")

    return {
        "dataset": dataset,
        "generated": generated,
        "session": _session(summary, declared_reference=validation is not None),
        "headline": digest.headline(calibration, results, validation, warnings),
        "gap_sentence": digest.gap_sentence(
            _optional_json(gap[0], "gap diagnosis") if gap else None
        ),
        "warnings": warnings,
        "methods": [
            {
                "sensor": SECTION_TITLES[section],
                "method": (
                    f"not calibrated: {not_calibrated[s]}"
                    if s in not_calibrated
                    else calibration[s].get("method") or "not stated"
                ),
            }
            for s, section in SENSOR_SECTIONS.items()
        ],
        "stages": None if stages is None else list(stages.get("stages", [])),
        "segmentation_figures": figure_items["segmentation"],
        "other_figures": figure_items["other"],
        "sensors": sensors,
        "tables": _paper_tables(tables),
        "tables_given": tables is not None,
        "calibration_meta": {
            k: str(calibration[k])
            for k in ("format_version", "frame", "convention")
            if k in calibration
        },
        "has_reference": REFERENCE in recordings or validation is not None,
        "validation": None if validation is None else flatten_fields(validation),
        "validation_tables": digest.validation_tables(validation),
        "validation_link": links["validation"],
        "validation_figures": figure_items["validation"],
        "provenance": {
            "imucal_version": imucal_version,
            "git_commit": git_commit,
            "snakemake_version": snakemake_version,
            "config": None if config is None else yaml.safe_dump(_plain(config), sort_keys=False),
        },
        "benchmarks": [
            {
                "rule": r.rule,
                "repeats": r.repeats,
                "s": format_number(r.s, 4),
                "max_rss_mb": format_number(r.max_rss_mb, 4),
            }
            for r in bench.itertuples()
        ],
        "benchmarks_total_s": format_number(float(bench["s"].sum()), 4) if len(bench) else None,
        "gap": _gap_section(gap),
        "noise": _noise_section(noise),
        "terms": _terms_section(terms, gap),
        "holdout": holdout_section(temperature_holdout),
    }


def _link(obj: Any, report_path: str | Path | None) -> str | None:
    """Path of a stage result given as a file, relative to the report's folder (for a link)."""
    if report_path is None or obj is None or isinstance(obj, Mapping):
        return None
    start = Path(report_path).resolve().parent
    return Path(os.path.relpath(Path(obj).resolve(), start)).as_posix()


def _plus_minus(value: Any, std: Any) -> str:
    """``value ± std`` for scalars, vectors and matrices alike."""
    return f"{format_value(value)} ± {format_value(std, 2)}"


def _heldout_row(term: str, h: Mapping) -> dict:
    """One row of the held-out table from a comparison of :mod:`imucal.terms.heldout`."""
    if "note" in h:
        return {"term": term, "residual": h["note"], "rms": "", "achieved": "", "predicted": "",
                "verdict": ""}  # fmt: skip
    predicted = h["predicted_shrink"]
    verdict = ("no prediction" if predicted is None else
               "short of the prediction" if h["short_of_prediction"] else "as predicted or better")  # fmt: skip
    return {
        "term": term,
        "residual": h["residual"],
        "rms": f"{format_number(h['rms_without'], 3)} → {format_number(h['rms_with'], 3)}",
        "achieved": _plus_minus(h["achieved_shrink"], h["achieved_std"]),
        "predicted": format_number(predicted, 2) if predicted is not None else "-",
        "verdict": verdict,
    }


def _terms_section(
    paths: Sequence[str | Path] | None, gap: Sequence[str | Path] | None
) -> dict | None:
    """Context of the model-terms partial (``_terms.html.j2``) from terms.json and
    gap/after.json (in that order), with the gap before from diagnosis.json."""
    if not paths:
        return None
    terms_path, after_path = paths
    summary = _load_json(terms_path, "model terms")
    after = _load_json(after_path, "diagnosis after the model terms")
    before = _load_json(gap[0], "gap diagnosis") if gap else {}
    rows = [
        {
            "term": name,
            "setting": r["setting"],
            "included": "in the model" if name in summary["in_model"] else "not in the model",
            "reason": r["reason"],
        }
        for name, r in summary["terms"].items()
    ]
    model = (summary.get("calibration") or {}).get("terms", {})
    values = []
    for sensor, poly in model.get("temperature", {}).items():
        for kind in ("bias", "scale"):
            for k, (c, sd) in enumerate(zip(poly[kind], poly[f"{kind}_std"], strict=True), 1):
                values.append({"term": f"temperature {sensor} {kind} dT^{k}",
                               "value": _plus_minus(c, sd), "unit": poly[f"{kind}_unit"]})  # fmt: skip
    if "g_sensitivity" in model:
        g = model["g_sensitivity"]
        values.append({"term": "g-sensitivity G", "value": _plus_minus(g["matrix"], g["std"]),
                       "unit": g["unit"]})  # fmt: skip
    if "lever_arm" in model:
        r = model["lever_arm"]
        values.append({"term": "lever arm r", "value": _plus_minus(r["r_m"], r["std_m"]),
                       "unit": r["unit"]})  # fmt: skip
    if "mag_delay" in model:
        m = model["mag_delay"]
        values.append({"term": "magnetometer delay", "value": _plus_minus(m["delay_s"], m["std_s"]),
                       "unit": m["unit"]})  # fmt: skip
    heldout = [_heldout_row(name, r["heldout"]) for name, r in summary["terms"].items()
               if r.get("heldout")]  # fmt: skip
    p2p = summary.get("heldout_pose_to_pose")
    if p2p and "note" not in p2p:
        heldout.append(_heldout_row("all terms in the model", p2p))
    gap_before = (before.get("gap") or {}).get("total")
    gap_after = (after.get("gap") or {}).get("total")
    compared = gap_comparison(before, after, summary["in_model"])
    return {
        "gap_compared": (
            {
                k: (v if k in ("verdict", "still_explained") else format_number(v))
                for k, v in compared.items()
            }  # fmt: skip
            if compared
            else None
        ),
        "rows": rows,
        "coefficients": values,
        "heldout": heldout,
        "in_model": summary["in_model"],
        "gap_before": format_number(gap_before),
        "gap_after": format_number(gap_after) if gap_after is not None else None,
        "remaining_after": format_number((after.get("remaining") or {}).get("total")),
        "explained_after": list(after.get("explained", [])),
        "note": after.get("note", ""),
    }


def _gap_section(paths: Sequence[str | Path] | None) -> dict | None:
    """Context of the gap-diagnosis partial (``_gap.html.j2``): diagnosis.json, then figures."""
    if not paths:
        return None
    from imucal.gap.figures import observations_context, report_context

    diagnosis, *figures = [Path(p) for p in paths]
    d = _load_json(diagnosis, "gap diagnosis")
    # a partial session's diagnosis (imucal.gap.static) says what it could score, or why not
    scope = {"scope": d.get("scope", "full"), "reason": d.get("reason", ""),
             "not_observable": d.get("not_observable", {}), "pose": d.get("pose")}  # fmt: skip
    if scope["scope"] == "none":
        return {**observations_context(d), **scope}
    return {**report_context(d, {f.stem: embed_figure(f) for f in figures}), **scope}


def _noise_section(paths: Sequence[str | Path] | None) -> dict | None:
    """Context of the noise partial (``_noise.html.j2``): noise.json, then its figure."""
    if not paths:
        return None
    from imucal.pipeline.outcome import not_run_reason

    path, *figures = [Path(p) for p in paths]
    d = _load_json(path, "noise")
    reason = not_run_reason(d)
    if reason:
        return {"reason": reason, "rows": [], "figure": None}
    rows = []
    for sensor, data in d["sensors"].items():
        for axis, fit in data["axes"].items():
            cells = {}
            for term, t in fit["terms"].items():
                if t["resolved"]:
                    cells[term] = f"{format_number(t['value'], 3)} ± {format_number(t['std'], 2)}"
                else:
                    cells[term] = f"< {format_number(t['upper_bound'], 3)}"
            rows.append({"sensor": sensor, "axis": axis, "cells": cells,
                         "chi2": format_number(fit["reduced_chi2"], 2)})  # fmt: skip
    units = {s: {t: next(iter(v["axes"].values()))["terms"][t]["unit"] for t in d["terms"]}
             for s, v in d["sensors"].items()}  # fmt: skip
    return {
        "reason": None,
        "recording": d["recording"],
        "duration_s": format_number(d["duration_s"], 4),
        "rate_hz": format_number(d["rate_hz"], 4),
        "level": format_number(d["level"], 3),
        "terms": d["terms"],
        "units": units,
        "rows": rows,
        "skipped": d.get("skipped", {}),
        "figure": embed_figure(figures[0]) if figures else None,
    }


def _plain(obj: Any) -> Any:
    """Plain YAML types (Snakemake's config holds its own Mapping and list classes)."""
    if isinstance(obj, Mapping):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    return obj


def _environment() -> jinja2.Environment:
    return jinja2.Environment(
        loader=jinja2.PackageLoader("imucal.report", "templates"),
        autoescape=True,
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
        keep_trailing_newline=True,
    )


def render_report(context: Mapping[str, Any]) -> str:
    """Render the HTML report from a :func:`build_report_context` context.

    Returns
    -------
    str
        One self-contained HTML5 document (inline CSS, embedded figures, no script).
    """
    return _environment().get_template("report.html.j2").render(**context)
