"""HTML lab report of one dataset: collect the artifacts into a context, render it (jinja2).

The report is one self-contained file: figures are embedded as base64 data URIs, the CSS is
inline, there is no script and a Content-Security-Policy forbids loading anything that is not in
the file, so it reads the same offline. :func:`build_report_context` takes every artifact
explicitly (paths or already-loaded objects; the rule script passes ``snakemake.input``, this
module never globs) and formats all numbers; :func:`render_report` only lays them out with the
template ``imucal/report/templates/report.html.j2``.

The sections' contents are built in :mod:`imucal.report.sections`, the figures embedded and
captioned in :mod:`imucal.report.figures`, the artifacts and benchmarks read in
:mod:`imucal.report.artifacts` and nested JSON rendered in :mod:`imucal.report.fields`; this
module assembles them into the context and renders it.
"""

from __future__ import annotations

import datetime as _dt
import os
from collections.abc import Mapping, Sequence
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any

import jinja2
import numpy as np
import pandas as pd
import yaml

import imucal
import imucal.report.digest as digest
from imucal.columns import SENSORS
from imucal.constants import REFERENCE
from imucal.pipeline.outcome import NOT_SHIPPED
from imucal.report.artifacts import load_json, optional_json, read_benchmarks
from imucal.report.consistency import consistency_section
from imucal.report.fields import collect_warnings, flatten_fields, log_warnings
from imucal.report.figures import _caption, embed_figure, figure_section
from imucal.report.gapsection import gap_section, reconcile_offset, verdict_sentence
from imucal.report.holdout import holdout_section
from imucal.report.numbers import format_number
from imucal.report.sections import (
    _RECORDING_ABSENT,
    RATE_TABLE,
    _noise_section,
    _paper_tables,
    _sensor_parameters,
    _session,
    _terms_section,
    undetermined_parameters,
)

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
    consistency: str | Path | Mapping | None = None,
    simulated: Mapping | None = None,
    logs: Sequence[str | Path] = (),
    dataset_folder: str | Path | None = None,
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
    consistency : mapping or path, optional
        ``consistency.json`` (:mod:`imucal.validation.consistency`): its own section, and its
        warnings among each sensor's.
    dataset_folder : path, optional
        The dataset's folder: the files table gives the raw files' paths relative to it.
    logs : sequence of path
        The log of every rule behind the report: their warnings (WARNING and above) are
        listed with the stages' own, repeats counted.
    simulated : mapping, optional
        The dataset's ``simulated`` declaration (:attr:`imucal.io.dataset.Dataset.simulated`):
        the report opens with a banner saying the data are simulated, what rendered them and
        what its "truth" rows are. None for recorded data: no banner.

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
    summary = load_json(summary, "ingest summary")
    calibration = load_json(calibration, "calibration")
    not_calibrated = dict(calibration.get("missing", {}))
    missing = [s for s in SENSORS if s not in calibration and s not in not_calibrated]
    if missing:
        raise ValueError(
            f"calibration lacks the sensors {missing} and gives no reason for them in 'missing'; "
            "expected acc, gyr and mag"
        )
    stages = optional_json(stages, "stages.json")
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
        "mag": optional_json(mag_result, "mag.json"),
        "acc": optional_json(acc_result, "acc.json"),
        "gyr": optional_json(gyr_result, "gyr.json"),
    }
    validation = optional_json(validation, "validation.json")
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

    consistency = optional_json(consistency, "consistency.json")
    warnings = run_warnings(
        results, validation, temperature_holdout, gap, noise, terms, stages, logs, consistency
    )

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

    diagnosis = optional_json(gap[0], "gap diagnosis") if gap else None
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
        "session": _session(
            summary, declared_reference=validation is not None, folder=dataset_folder
        ),
        "simulated": None
        if simulated is None
        else {
            "by": str(simulated.get("by", "a simulator")),
            "truth": Path(simulated["truth"]).name if simulated.get("truth") else None,
        },
        "headline": digest.headline(
            calibration,
            results,
            validation,
            warnings,
            {
                s: undetermined_parameters(s, calibration[s], recordings)
                for s in SENSORS
                if s not in not_calibrated
            },
        ),
        "gap_sentence": verdict_sentence(diagnosis),
        "warnings": warnings,
        "summary_warnings": digest.merged_warnings(warnings),
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
        # a stage that ran needs no reason (the listing repeats what it does there)
        "stages": None
        if stages is None
        else [
            {**row, "reason": "" if row.get("reason") == row.get("what") else row.get("reason")}
            for row in stages.get("stages", [])
        ],
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
        "validation_tables": digest.validation_tables(
            validation, reconcile_offset(diagnosis, validation, summary)
        ),
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
        "gap": gap_section(gap, validation, summary),
        "noise": _noise_section(noise),
        "terms": _terms_section(terms, gap),
        "holdout": holdout_section(temperature_holdout),
        "consistency": consistency_section(consistency),
    }


def run_warnings(
    results: Mapping[str, Mapping | None],
    validation: Mapping | None,
    temperature_holdout: str | Path | None,
    gap: Sequence[str | Path] | None,
    noise: Sequence[str | Path] | None,
    terms: Sequence[str | Path] | None,
    stages: Mapping | None,
    logs: Sequence[str | Path],
    consistency: Mapping | None = None,
) -> list[dict]:
    """Every warning of the run: the stage results' (``warnings`` lists at any depth), the
    consistency check's per sensor, the refused fits of the stage listing, and every rule's
    log (repeats counted).

    Returns
    -------
    list of dict
        ``source``, ``where``, ``text``, ``count`` and ``summary`` (its short form).
    """
    warnings: list[dict] = []
    for sensor, result in results.items():
        if result is not None:
            warnings += collect_warnings(result, f"{sensor}.json")
    if validation is not None:
        warnings += collect_warnings(validation, "validation.json")
    if temperature_holdout is not None:
        holdout = load_json(temperature_holdout, "temperature_holdout.json")
        warnings += collect_warnings(holdout, "temperature_holdout.json")
    for name, paths in (("gap/diagnosis.json", gap), ("noise.json", noise), ("terms.json", terms)):
        if paths:
            warnings += collect_warnings(load_json(paths[0], name), name)
    for sensor, entry in (consistency or {}).get("sensors", {}).items():
        # the sensor first, so that the summary lists them among the sensor's warnings
        warnings += collect_warnings(entry, f"{sensor} (consistency.json)")
    # a stage whose fit was refused (the simpler one's calibration is shipped) says why here too
    warnings += [
        {"source": "stages.json", "where": row["stage"], "text": row["reason"]}
        for row in (stages or {}).get("stages", [])
        if str(row.get("reason", "")).startswith(NOT_SHIPPED)
    ]
    warnings = [{"count": 1, **w} for w in warnings] + log_warnings(logs)
    for w in warnings:
        w["summary"] = digest.short_warning(w)
    return warnings


def _link(obj: Any, report_path: str | Path | None) -> str | None:
    """Path of a stage result given as a file, relative to the report's folder (for a link)."""
    if report_path is None or obj is None or isinstance(obj, Mapping):
        return None
    start = Path(report_path).resolve().parent
    return Path(os.path.relpath(Path(obj).resolve(), start)).as_posix()


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
