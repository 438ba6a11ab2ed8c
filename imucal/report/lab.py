"""HTML lab report of one dataset: collect the artifacts into a context, render it (jinja2).

The report is one self-contained file: figures are embedded as base64 data URIs, the CSS is
inline, there is no script and a Content-Security-Policy forbids loading anything that is not in
the file, so it reads the same offline. :func:`build_report_context` takes every artifact
explicitly (:class:`~imucal.report.inputs.ReportInputs`: paths or already-loaded objects; the
rule script passes ``snakemake.input``, nothing globs), loads what the sections share once
(:func:`~imucal.report.inputs.load_report`) and lays it out with one builder per section, all
numbers formatted; :func:`render_report` only lays them out with the template
``imucal/report/templates/report.html.j2``.

The sections' contents are built here and in :mod:`imucal.report.sections` (and the modules of
the gap, noise, hold-out and consistency sections), the figures embedded and captioned in
:mod:`imucal.report.figures`, the artifacts and benchmarks read in :mod:`imucal.report.artifacts`
and nested JSON rendered in :mod:`imucal.report.fields`.
"""

from __future__ import annotations

import datetime as _dt
from collections.abc import Mapping, Sequence
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any

import jinja2
import numpy as np
import yaml

import imucal
import imucal.report.digest as digest
from imucal.columns import SENSORS
from imucal.constants import REFERENCE
from imucal.pipeline.outcome import NOT_SHIPPED
from imucal.report.artifacts import load_json, read_benchmarks
from imucal.report.consistency import consistency_section
from imucal.report.fields import collect_warnings, flatten_fields, log_warnings
from imucal.report.gapsection import gap_section, reconcile_offset, verdict_sentence
from imucal.report.holdout import holdout_section
from imucal.report.inputs import (
    SECTION_TITLES,
    SENSOR_SECTIONS,
    LoadedReport,
    ReportInputs,
    load_report,
)
from imucal.report.numbers import format_number
from imucal.report.sections import (
    RATE_TABLE,
    RECORDING_ABSENT,
    noise_section,
    paper_tables,
    sensor_parameters,
    session_section,
    terms_section,
    undetermined_parameters,
)


def build_report_context(inputs: ReportInputs) -> dict:
    """Collect the artifacts of one dataset into the context of the report template: the
    loader's (:func:`~imucal.report.inputs.load_report`) artifacts laid out by each section's
    builder.

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
    loaded = load_report(inputs)
    warnings = run_warnings(
        loaded.results,
        loaded.validation,
        inputs.temperature_holdout,
        inputs.gap,
        inputs.noise,
        inputs.terms,
        loaded.stages,
        inputs.logs,
        loaded.consistency,
    )
    sensors = sensor_sections(loaded)
    return {
        "dataset": inputs.dataset,
        **provenance_section(inputs),
        "session": session_section(
            loaded.summary,
            declared_reference=loaded.validation is not None,
            folder=inputs.dataset_folder,
        ),
        "simulated": simulated_banner(inputs.simulated),
        **summary_section(loaded, warnings),
        "segmentation_figures": loaded.figures["segmentation"],
        "other_figures": loaded.figures["other"],
        "sensors": sensors,
        **calibration_section(loaded),
        **validation_section(loaded),
        **benchmark_section(inputs),
        "gap": gap_section(inputs.gap, loaded.validation, loaded.summary),
        "noise": noise_section(inputs.noise),
        "terms": terms_section(inputs.terms, inputs.gap),
        "holdout": holdout_section(inputs.temperature_holdout),
        "consistency": consistency_section(loaded.consistency),
    }


def sensor_sections(loaded: LoadedReport) -> list[dict]:
    """Each sensor's section, in report order: its parameters, stage results, tables, figures
    and notes, or why it was not calibrated."""
    sensors = []
    for sensor, section in SENSOR_SECTIONS.items():
        result = loaded.results[sensor]
        common = {
            "id": section,
            "title": SECTION_TITLES[section],
            "result_file": f"{sensor}.json",
            "link": loaded.links[sensor],
            "figures": loaded.figures[section],
        }
        if sensor in loaded.not_calibrated:
            sensors.append({
                **common, "parameters": None, "result": None, "tables": [],
                "notes": [f"Not calibrated: {loaded.not_calibrated[sensor]}"],
            })  # fmt: skip
            continue
        no_table = sensor == "gyr" and RATE_TABLE not in loaded.recordings
        sensors.append({
            **common,
            "parameters": sensor_parameters(sensor, loaded.calibration[sensor]),
            "result": None if result is None else flatten_fields(result),
            "tables": digest.stage_tables(sensor, result),
            "notes": [RECORDING_ABSENT[RATE_TABLE]] if no_table else [],
        })  # fmt: skip
    return sensors


def summary_section(loaded: LoadedReport, warnings: list[dict]) -> dict:
    """The report's summary: the headline, the gap's verdict in a sentence, the warnings (all
    and merged), each sensor's method and the stages run and skipped."""
    calibration, not_calibrated = loaded.calibration, loaded.not_calibrated
    undetermined = {
        s: undetermined_parameters(s, calibration[s], loaded.recordings)
        for s in SENSORS
        if s not in not_calibrated
    }
    methods = [
        {
            "sensor": SECTION_TITLES[section],
            "method": (
                f"not calibrated: {not_calibrated[s]}"
                if s in not_calibrated
                else calibration[s].get("method") or "not stated"
            ),
        }
        for s, section in SENSOR_SECTIONS.items()
    ]
    stages = None
    if loaded.stages is not None:
        # a stage that ran needs no reason (the listing repeats what it does there)
        stages = [
            {**row, "reason": "" if row.get("reason") == row.get("what") else row.get("reason")}
            for row in loaded.stages.get("stages", [])
        ]
    return {
        "headline": digest.headline(
            calibration, loaded.results, loaded.validation, warnings, undetermined
        ),
        "gap_sentence": verdict_sentence(loaded.diagnosis),
        "warnings": warnings,
        "summary_warnings": digest.merged_warnings(warnings),
        "methods": methods,
        "stages": stages,
    }


def calibration_section(loaded: LoadedReport) -> dict:
    """The paper's tables and the calibration's metadata."""
    return {
        "tables": paper_tables(loaded.tables),
        "tables_given": loaded.tables is not None,
        "calibration_meta": {
            k: str(loaded.calibration[k])
            for k in ("format_version", "frame", "convention")
            if k in loaded.calibration
        },
    }


def validation_section(loaded: LoadedReport) -> dict:
    """The validation against the reference: its fields, tables (the clock offset reconciled
    with the gap diagnosis's), link and figures."""
    validation = loaded.validation
    offset = reconcile_offset(loaded.diagnosis, validation, loaded.summary)
    return {
        "has_reference": REFERENCE in loaded.recordings or validation is not None,
        "validation": None if validation is None else flatten_fields(validation),
        "validation_tables": digest.validation_tables(validation, offset),
        "validation_link": loaded.links["validation"],
        "validation_figures": loaded.figures["validation"],
    }


def simulated_banner(simulated: Mapping | None) -> dict | None:
    """The banner of a simulated dataset (what rendered it and its truth file), None for
    recorded data."""
    if simulated is None:
        return None
    return {
        "by": str(simulated.get("by", "a simulator")),
        "truth": Path(simulated["truth"]).name if simulated.get("truth") else None,
    }


def provenance_section(inputs: ReportInputs) -> dict:
    """When the report was generated and by which versions, commit and settings."""
    snakemake_version = inputs.snakemake_version
    if snakemake_version is None:
        try:
            snakemake_version = version("snakemake")
        except PackageNotFoundError:
            snakemake_version = "unknown"
    config = inputs.config
    return {
        "generated": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")
        if inputs.generated is None
        else inputs.generated,
        "provenance": {
            "imucal_version": imucal.__version__
            if inputs.imucal_version is None
            else inputs.imucal_version,
            "git_commit": inputs.git_commit,
            "snakemake_version": snakemake_version,
            "config": None if config is None else yaml.safe_dump(_plain(config), sort_keys=False),
        },
    }


def benchmark_section(inputs: ReportInputs) -> dict:
    """The rules' run times and peak memory (Snakemake's benchmark files) and their total."""
    bench = read_benchmarks(inputs.benchmarks, inputs.dataset)
    return {
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
