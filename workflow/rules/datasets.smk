# The datasets of a run: the config's and the public recordings' (config/real), the fleet's
# sample sheet, each dataset's config sections and dataset.yaml, read once and checked when the
# workflow is parsed. No rules here.
import os
from functools import lru_cache
from pathlib import Path

import yaml
from snakemake.exceptions import WorkflowError
from snakemake.utils import validate

import imucal
from imucal.constants import RECORDING_NAMES
from imucal.fleet import read_sample_sheet
from imucal.io.configfile import config_problem
from imucal.io.dataset import read_dataset
from imucal.pipeline.options import PipelineOptions, pipeline_settings
from imucal.pipeline.registry import is_full_protocol
from imucal.terms import poseholdout

DATASETS = sorted(config["datasets"])
#: The public recordings' configs (config/real/*.yaml), each checked against the schema
#: without filling defaults: what one sets beside `datasets` overrides the global config for
#: its datasets alone (e.g. `segmentation` for a logger's assumed rate).
REAL_CONFIGS = {
    path.stem: yaml.safe_load(path.read_text()) or {}
    for path in sorted(Path(workflow.basedir, "config", "real").glob("*.yaml"))
}
for _name, _real in REAL_CONFIGS.items():
    _problem = config_problem(
        _real,
        Path(workflow.basedir, "workflow", "schemas", "config.schema.yaml"),
        [Path("config", "real", f"{_name}.yaml")],
    )
    if _problem:
        raise WorkflowError(_problem)
    validate(_real, "../schemas/config.schema.yaml", set_default=False)
#: The public recordings (data into ../shared/data/real), run by `real`.
REAL_DATASETS = {
    name: folder
    for real in REAL_CONFIGS.values()
    for name, folder in real.get("datasets", {}).items()
}
#: The sessions of a fleet's sample sheet (config `fleet.sessions`, target `fleet`).
FLEET_SHEET = (
    read_sample_sheet(config["fleet"]["sessions"]) if config["fleet"]["sessions"] else None
)
SHEET_DATASETS = (
    {} if FLEET_SHEET is None else dict(zip(FLEET_SHEET["dataset"], FLEET_SHEET["path"]))
)
#: Package version as a param of every fit rule: an upgrade of imucal reruns them.
IMUCAL_VERSION = imucal.__version__
#: Every setting that changes a fit, read from the config once: the stage rules take theirs
#: from here, and the in-process chain (diagnosis, closed loop, partial path) gets the whole
#: dict, so the two agree by construction (imucal.pipeline.options).
PIPELINE_SETTINGS = pipeline_settings(config)
FIT_METHODS = PIPELINE_SETTINGS["methods"]


wildcard_constraints:
    dataset="[a-z0-9_]+",
    recording="|".join(RECORDING_NAMES),


def folder_of(name):
    """Folder of a dataset (config `datasets`, else the public recordings of config/real)."""
    folders = {**REAL_DATASETS, **SHEET_DATASETS, **config["datasets"]}
    if name not in folders:
        raise ValueError(
            f"dataset {name!r} is neither in config 'datasets', nor in config/real, nor in the "
            "fleet's sample sheet"
        )
    return str(Path(folders[name]))


#: Config sections a config/real file may set for its datasets alone.
DATASET_SECTIONS = ("segmentation", "noise")
#: Config sections of the checks (blind, stress, detection), not of one dataset's run.
CHECK_SECTIONS = ("datasets", "blind", "stress", "detection", "fleet")


def dataset_config(name, section):
    """One config section of a dataset: global, updated by its config/real file."""
    settings = dict(config[section])
    if section in DATASET_SECTIONS:
        for real in REAL_CONFIGS.values():
            if name in real.get("datasets", {}):
                settings.update(real.get(section, {}))
    return settings


def segmentation_settings(wildcards):
    """The `segmentation` config of a dataset (a rule param)."""
    return dataset_config(wildcards.dataset, "segmentation")


def run_settings(wildcards):
    """The settings one dataset's run used, as its report records them: its folder and every
    config section of the pipeline (with the dataset's config/real overrides)."""
    settings = {"datasets": {wildcards.dataset: folder_of(wildcards.dataset)}}
    for key, value in config.items():
        if key in CHECK_SECTIONS:
            continue
        is_section = isinstance(value, dict)
        settings[key] = dataset_config(wildcards.dataset, key) if is_section else value
    return settings


def dataset_folder(wildcards):
    """Folder of a dataset, relative paths taken from the working directory."""
    return folder_of(wildcards.dataset)


@lru_cache(maxsize=None)
def dataset_of(name):
    """The Dataset of a name, read once per workflow run (input functions ask many times)."""
    return read_dataset(folder_of(name))


def config_source(name):
    """Where config `datasets` got the dataset `name`: the last config file that names it (a
    --configfile overrides config/config.yaml), or the command line's --config."""
    for path in reversed(workflow.configfiles):
        data = yaml.safe_load(Path(path).read_text()) or {}
        if name in (data.get("datasets") or {}):
            path = Path(path).absolute()
            inside = path.is_relative_to(Path.cwd())
            return str(path.relative_to(Path.cwd())) if inside else str(path)
    return "the command line (--config)"


def check_configured_datasets():
    """Read the dataset.yaml of every configured dataset when the workflow is parsed, so that a
    wrong folder or setting stops the run before any rule, in one paragraph that names the
    config file, the dataset's key, the folder and the fix (a raised error, no traceback)."""
    for name, folder in sorted(config["datasets"].items()):
        source = f"{config_source(name)}, datasets.{name}: {folder!r}"
        try:
            dataset_of(name)
        except FileNotFoundError:
            where = Path(os.path.normpath(Path.cwd() / folder))  # as typed, symlinks kept
            missing = "has no dataset.yaml" if where.is_dir() else "does not exist"
            raise WorkflowError(
                f"{source}: the folder {where} {missing}. Give the folder that holds the "
                f"dataset's dataset.yaml (relative to {Path.cwd()}, or absolute), or remove "
                f"'{name}' from datasets; docs/data-format.md describes the folder."
            ) from None
        except ValueError as err:
            raise WorkflowError(
                f"{source}: {err} Fix the file and run again; docs/data-format.md lists the "
                "settings."
            ) from None


def full_protocol(name):
    """The session follows the paper's protocol (stage-per-rule workflow), else `partial`."""
    return is_full_protocol(dataset_of(name))


check_configured_datasets()
#: The configured and public datasets: a lab report is one of theirs (reports/blind.html and
#: reports/stress.html are the checks' pages, not datasets).
ALL_DATASETS_PATTERN = (
    "|".join(sorted({**REAL_DATASETS, **SHEET_DATASETS, **config["datasets"]})) or "(?!)"
)


def datasets_pattern(full):
    """Regex of the configured and public datasets on one path (full protocol or partial).

    Evaluated when the workflow is parsed: a dataset whose dataset.yaml cannot be read (e.g.
    the public recordings' configs in a copy without data/real) is on neither path; asking
    for its outputs then fails on that dataset alone, with the reader's message.
    """
    names = []
    for name in sorted({**REAL_DATASETS, **SHEET_DATASETS, **config["datasets"]}):
        try:
            on_path = full_protocol(name) == full
        except (FileNotFoundError, ValueError):
            continue
        if on_path:
            names.append(name)
    return "|".join(names) if names else "(?!)"


def dataset_info(wildcards):
    return dataset_of(wildcards.dataset)


def dataset_yaml(wildcards):
    return str(Path(dataset_folder(wildcards)) / "dataset.yaml")


def has_recording(wildcards, recording):
    return recording in dataset_info(wildcards).recordings


def pipeline_options(wildcards):
    """The settings that change a fit for one dataset: its dataset.yaml's and the config's."""
    return PipelineOptions.of_dataset(dataset_info(wildcards), **PIPELINE_SETTINGS)


def noise_settings(name):
    """The `noise` config of a dataset."""
    return dataset_config(name, "noise")


def noise_setting(key):
    """Input function of one `noise` setting of the dataset (a rule param)."""

    def setting(wildcards):
        return noise_settings(wildcards.dataset)[key]

    return setting


def has_noise_recording(name):
    """The dataset has the recording the noise stage analyses (static by default)."""
    return noise_settings(name)["recording"] in dataset_of(name).recordings


def holdout_recording(name):
    """The recording with declared static poses and a temperature channel, or None."""
    return poseholdout.holdout_recording(dataset_of(name))


def has_orientation_reference(name):
    return bool(dataset_of(name).orientation_references)


def calibration_path(name):
    """The calibration a session ships, whichever path made it."""
    return f"results/{name}/calibration.json"
