"""What the lab report of one dataset is built from: its inputs (:class:`ReportInputs`, paths or
already-loaded objects; the rule script passes ``snakemake.input``, nothing here globs) and the
one loader (:func:`load_report`) that reads the artifacts the sections share, checks them and
groups the figures by section. The sections' builders (:mod:`imucal.report.lab`,
:mod:`imucal.report.sections` and the modules of each section) take what it loaded.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd

from imucal.columns import SENSORS
from imucal.report.artifacts import load_json, optional_json
from imucal.report.figures import embed_figure, figure_caption, figure_section

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


@dataclass(frozen=True)
class ReportInputs:
    """The artifacts and the provenance of one dataset's lab report.

    Attributes
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
        :func:`~imucal.report.figures.figure_section`, in the order given.
    captions : mapping, optional
        File stem -> caption; overrides :data:`~imucal.report.figures.DEFAULT_CAPTIONS`.
    benchmarks : sequence of path or mapping label -> path
        Snakemake benchmark TSV files (:func:`~imucal.report.artifacts.read_benchmarks`).
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
    gap : sequence of path, optional
        ``gap/diagnosis.json`` (its first entry): the gap section, the summary's verdict and
        the reference's clock offset reconciled with the validation's.
    noise : sequence of path, optional
        ``noise.json`` (its first entry): the noise section.
    terms : sequence of path, optional
        ``terms.json`` and the diagnosis after the terms: the model terms' section.
    """

    dataset: str
    summary: Mapping | str | Path
    calibration: Mapping | str | Path
    mag_result: Mapping | str | Path | None = None
    acc_result: Mapping | str | Path | None = None
    gyr_result: Mapping | str | Path | None = None
    validation: Mapping | str | Path | None = None
    tables: pd.DataFrame | str | Path | None = None
    stages: Mapping | str | Path | None = None
    figures: Sequence[str | Path] = ()
    captions: Mapping[str, str] | None = None
    benchmarks: Sequence[str | Path] | Mapping[str, str | Path] = ()
    config: Mapping | None = None
    git_commit: str = "unknown"
    snakemake_version: str | None = None
    imucal_version: str | None = None
    generated: str | None = None
    gap: Sequence[str | Path] | None = None
    noise: Sequence[str | Path] | None = None
    terms: Sequence[str | Path] | None = None
    report_path: str | Path | None = None
    temperature_holdout: str | Path | None = None
    consistency: str | Path | Mapping | None = None
    simulated: Mapping | None = None
    logs: Sequence[str | Path] = ()
    dataset_folder: str | Path | None = None


@dataclass(frozen=True)
class LoadedReport:
    """The artifacts the report's sections share, loaded and checked once.

    Attributes
    ----------
    inputs : ReportInputs
        As given (the files only one section reads are read by its builder).
    summary, calibration : dict
        The ingest summary and the calibration.
    not_calibrated : dict
        Sensor -> why a partial session could not calibrate it (``missing``).
    recordings : dict
        The summary's recordings by name.
    stages, validation, consistency, diagnosis : dict or None
        ``stages.json``, ``validation.json``, ``consistency.json``, ``gap/diagnosis.json``.
    results : dict
        Sensor -> its stage results (``mag.json`` ...) or None.
    links : dict
        ``mag``, ``acc``, ``gyr``, ``validation`` -> the path of the file relative to the
        report's folder, or None.
    tables : DataFrame or None
        ``tables.csv``.
    figures : dict
        Section -> its figures (``src``, ``caption``, ``file``, ``number``), in report order.
    """

    inputs: ReportInputs
    summary: dict
    calibration: dict
    not_calibrated: dict
    recordings: dict
    stages: dict | None
    validation: dict | None
    consistency: dict | None
    diagnosis: dict | None
    results: dict
    links: dict
    tables: pd.DataFrame | None
    figures: dict


def load_report(inputs: ReportInputs) -> LoadedReport:
    """Read and check the artifacts the report's sections share.

    Raises
    ------
    FileNotFoundError
        If a given file does not exist.
    ValueError
        If an artifact has the wrong form (see the loaders), or the calibration lacks a sensor
        without giving the reason in ``missing``.
    """
    summary = load_json(inputs.summary, "ingest summary")
    calibration = load_json(inputs.calibration, "calibration")
    not_calibrated = dict(calibration.get("missing", {}))
    missing = [s for s in SENSORS if s not in calibration and s not in not_calibrated]
    if missing:
        raise ValueError(
            f"calibration lacks the sensors {missing} and gives no reason for them in 'missing'; "
            "expected acc, gyr and mag"
        )
    stages = optional_json(inputs.stages, "stages.json")
    given = {
        "mag": inputs.mag_result,
        "acc": inputs.acc_result,
        "gyr": inputs.gyr_result,
        "validation": inputs.validation,
    }
    links = {name: _link(obj, inputs.report_path) for name, obj in given.items()}
    # in report order: the warnings are listed in it
    results = {s: optional_json(given[s], f"{s}.json") for s in SENSOR_SECTIONS}
    validation = optional_json(inputs.validation, "validation.json")
    tables = inputs.tables
    if tables is not None and not isinstance(tables, pd.DataFrame):
        tables = pd.read_csv(tables)
    figures = _figures(inputs.figures, dict(inputs.captions or {}))
    consistency = optional_json(inputs.consistency, "consistency.json")
    diagnosis = optional_json(inputs.gap[0], "gap diagnosis") if inputs.gap else None
    return LoadedReport(
        inputs,
        summary,
        calibration,
        not_calibrated,
        summary.get("recordings", {}),
        stages,
        validation,
        consistency,
        diagnosis,
        results,
        links,
        tables,
        figures,
    )


def _figures(paths: Sequence[str | Path], captions: Mapping[str, str]) -> dict[str, list[dict]]:
    """The figures grouped by section (in report order), then numbered as they appear."""
    items: dict[str, list[dict]] = {name: [] for name in SECTION_TITLES}
    for path in map(Path, paths):
        items[figure_section(path)].append(
            {
                "src": embed_figure(path),
                "caption": figure_caption(path, captions),
                "file": path.name,
            }
        )
    for number, item in enumerate((item for group in items.values() for item in group), start=1):
        item["number"] = number
    return items


def _link(obj: Any, report_path: str | Path | None) -> str | None:
    """Path of a stage result given as a file, relative to the report's folder (for a link)."""
    if report_path is None or obj is None or isinstance(obj, Mapping):
        return None
    start = Path(report_path).resolve().parent
    return Path(os.path.relpath(Path(obj).resolve(), start)).as_posix()
