# Helpers shared by the rules: the dataset table, input functions, wildcard constraints.
# No rules here.
import os
from functools import lru_cache
from pathlib import Path

import yaml
from snakemake.exceptions import WorkflowError
from snakemake.utils import validate

import imucal
from imucal.constants import IMU_RECORDINGS, RECORDING_NAMES
from imucal.terms import TermSettings
from imucal.fleet import read_sample_sheet
from imucal.gap.composite import partial_scope
from imucal.io.dataset import read_dataset
from imucal.pipeline.options import pipeline_settings
from imucal.pipeline.registry import full_protocol_artifacts, is_full_protocol
from imucal.terms import poseholdout

DATASETS = sorted(config["datasets"])
#: The public recordings' configs (config/real/*.yaml), each checked against the schema
#: without filling defaults: what one sets beside `datasets` overrides the global config for
#: its datasets alone (e.g. `segmentation` for a logger's assumed rate).
REAL_CONFIGS = {
    path.stem: yaml.safe_load(path.read_text()) or {}
    for path in sorted(Path(workflow.basedir, "config", "real").glob("*.yaml"))
}
for _real in REAL_CONFIGS.values():
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


def diagnosis_for_terms(wildcards):
    """The session's diagnosis when a model term is 'auto' (the loop decides on it), else none."""
    if TermSettings.from_config(config["terms"]).needs_diagnosis:
        return f"results/{wildcards.dataset}/gap/diagnosis.json"
    return []


def gap_partial_scope(wildcards):
    """Which parts of a partial session the gap diagnosis scores (imucal.gap.composite.partial_scope)."""
    return partial_scope(
        static=has_recording(wildcards, "static"),
        references=bool(dataset_info(wildcards).orientation_references),
        poses=holdout_recording(wildcards.dataset) is not None,
    )


def gap_partial_inputs(wildcards):
    """A partial session's calibration and the recordings of its diagnosis's scope
    (gap_partial_scope): its static recording, its recordings with an orientation reference
    (with the references and the segments), its declared static poses with a temperature
    channel, or all its recordings and segments, whose rests are scored."""
    d = wildcards.dataset
    scope = gap_partial_scope(wildcards)
    inputs = {"calibration": f"results/{d}/partial/calibration.json"}
    if "static" in scope:
        inputs["static"] = f"results/{d}/ingest/static.parquet"
    if "reference" in scope:
        inputs |= {f"moving_{n}": p for n, p in orientation_recordings(wildcards).items()}
        inputs["orientation"] = orientation_references(wildcards)
    elif scope == "poses":
        inputs["poses"] = holdout_input(wildcards)
    elif scope == "rests":
        inputs |= {f"rest_{n}": p for n, p in ingested_imu_all(wildcards).items()}
    if scope != "static":
        inputs["segments"] = f"results/{d}/segments.parquet"
    return inputs


def dataset_info(wildcards):
    return dataset_of(wildcards.dataset)


def dataset_yaml(wildcards):
    return str(Path(dataset_folder(wildcards)) / "dataset.yaml")


def raw_recording(wildcards):
    """Every file one recording reads (streams, parts, section list), as named in dataset.yaml."""
    info = dataset_info(wildcards)
    return [str(path) for path in info.recording_files(wildcards.recording)]


def ingested(wildcards):
    """All ingested recordings of a dataset, by recording name."""
    info = dataset_info(wildcards)
    return {name: f"results/{wildcards.dataset}/ingest/{name}.parquet" for name in info.recordings}


def ingested_imu(wildcards):
    """Ingested IMU recordings (not the reference) of a dataset, by recording name."""
    info = dataset_info(wildcards)
    return {
        name: f"results/{wildcards.dataset}/ingest/{name}.parquet"
        for name in IMU_RECORDINGS
        if name in info.recordings
    }


def ingested_imu_all(wildcards):
    """Every ingested recording of the module (all roles, not the reference), by name."""
    info = dataset_info(wildcards)
    return {
        name: f"results/{wildcards.dataset}/ingest/{name}.parquet"
        for name in info.recordings
        if name != "reference"
    }


def stages_listing(wildcards):
    """stages.json comes from the path the session takes."""
    d = wildcards.dataset
    path = "full" if full_protocol(d) else "partial"
    return f"results/{d}/{path}/stages.json"


#: Artifact of each stage of the stage-per-rule path (stages.json reads what ran from them).
FULL_STAGE_ARTIFACTS = full_protocol_artifacts()


def full_stage_artifacts(wildcards):
    """The stage artifacts of a full-protocol session (no rate-table fit without a table)."""
    d = wildcards.dataset
    return {
        stage: f"results/{d}/{name}"
        for stage, name in FULL_STAGE_ARTIFACTS.items()
        if stage != "gyr_table" or has_recording(wildcards, "ratetable")
    }


def has_recording(wildcards, recording):
    return recording in dataset_info(wildcards).recordings


def gyr_bias_inputs(wildcards):
    """The static recording, or the recordings whose static pauses stand in for it."""
    names = ["static"] if has_recording(wildcards, "static") else ["rotation3d", "cube"]
    return {name: f"results/{wildcards.dataset}/ingest/{name}.parquet" for name in names}


def gyr_table_inputs(wildcards):
    """Rate-table artifacts when the dataset has a rate table, else nothing."""
    if not has_recording(wildcards, "ratetable"):
        return {}
    return {
        "table": f"results/{wildcards.dataset}/gyr_table.json",
        "table_alignment": f"results/{wildcards.dataset}/gyr_table_align.json",
    }


def truth_input(wildcards):
    """truth.json of a simulated or conformance dataset (for the truth rows of tables.csv)."""
    path = Path(dataset_folder(wildcards)) / "truth.json"
    return {"truth": str(path)} if path.is_file() else {}


def saturation_limit(sensor):
    """Input function: sensor range in SI units (range_counts * sensitivity)."""

    def limit(wildcards):
        info = dataset_info(wildcards)
        return info.range_counts[sensor] * info.sensitivity[sensor]

    return limit


def gravity(wildcards):
    return dataset_info(wildcards).gravity_m_s2


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


def noise_input(wildcards):
    recording = noise_settings(wildcards.dataset)["recording"]
    return {"recording": f"results/{wildcards.dataset}/ingest/{recording}.parquet"}


def calibration_path(name):
    """calibration.json of the path a session takes (full protocol or partial)."""
    path = "calibration.json" if full_protocol(name) else "partial/calibration.json"
    return f"results/{name}/{path}"


def calibration_of(wildcards):
    """Input function: the dataset's calibration.json (:func:`calibration_path`)."""
    return calibration_path(wildcards.dataset)


#: Files of the export rule (imucal.export.FORMATS), under results/{dataset}/export/, one folder
#: per format.
from imucal.export.formats import FORMATS as EXPORT_FORMATS

EXPORT_FILES = [f"{fmt}/{name}" for fmt, names in EXPORT_FORMATS.items() for name in names]


def noise_targets(name):
    """noise.json, its figure and the exports of a dataset with a static recording."""
    if not has_noise_recording(name):
        return []
    exports = [f"results/{name}/export/{f}" for f in EXPORT_FILES]
    return [f"results/{name}/noise.json", *exports]


def holdout_recording(name):
    """The recording with declared static poses and a temperature channel, or None."""
    return poseholdout.holdout_recording(dataset_of(name))


def holdout_report_inputs(name):
    """The temperature hold-out section's input when the dataset has one."""
    if holdout_recording(name) is None:
        return {}
    return {"temperature_holdout": f"results/{name}/temperature_holdout.json"}


def holdout_recording_param(wildcards):
    """The name of the recording of the temperature hold-out (a rule param)."""
    return holdout_recording(wildcards.dataset)


def holdout_input(wildcards):
    """The ingested recording of the temperature hold-out."""
    return f"results/{wildcards.dataset}/ingest/{holdout_recording(wildcards.dataset)}.parquet"


def dataset_targets(name):
    """Final outputs of one dataset: its report, calibration, stage listing and plots."""
    recordings = dataset_of(name).recordings
    targets = [f"results/{name}/ingest/summary.json", f"reports/{name}.html"]
    targets += [f"results/{name}/stages.json"]
    if full_protocol(name):
        targets += [f"results/{name}/calibration.json", f"results/{name}/tables.csv"]
        targets += [f"results/{name}/gap/diagnosis.json"]
    else:
        targets += [f"results/{name}/partial/calibration.json"]
        targets += [f"results/{name}/gap/diagnosis.json"]
        if has_orientation_reference(name):
            targets += [f"results/{name}/reference/validation.json"]
    targets += [f"results/{name}/segments/{r}.png" for r in recordings if r != "reference"]
    targets += noise_targets(name)
    targets += list(holdout_report_inputs(name).values())
    return targets


def all_targets(wildcards):
    """Final outputs of every configured dataset (read lazily, only when `all` is requested)."""
    return [t for name in DATASETS for t in dataset_targets(name)]


def real_targets(wildcards):
    """Final outputs of every public recording of config/real."""
    if not REAL_DATASETS:
        raise ValueError("config/real holds no dataset configs")
    return [t for name in sorted(REAL_DATASETS) for t in dataset_targets(name)]


def mag_step1_inputs(wildcards):
    """rotation3d, and the cube's magnetometer samples offered for coverage."""
    names = ["rotation3d"] + (["cube"] if has_recording(wildcards, "cube") else [])
    return {name: f"results/{wildcards.dataset}/ingest/{name}.parquet" for name in names}


def field_norm(wildcards):
    return dataset_info(wildcards).field_norm


def orientation_files(wildcards):
    """Every file the orientation reference of one recording reads (dataset.yaml)."""
    from imucal.io.readers import declared_files

    declaration = dataset_info(wildcards).orientation_references[wildcards.recording]
    return [str(path) for path in declared_files(declaration)]


def orientation_references(wildcards):
    """Ingested orientation references of a dataset (empty without any)."""
    d = wildcards.dataset
    names = sorted(dataset_info(wildcards).orientation_references)
    return [f"results/{d}/reference/{name}.parquet" for name in names]


def orientation_recordings(wildcards):
    """The ingested recordings that carry an orientation reference, by name."""
    d = wildcards.dataset
    names = sorted(dataset_info(wildcards).orientation_references)
    return {name: f"results/{d}/ingest/{name}.parquet" for name in names}


def has_orientation_reference(name):
    return bool(dataset_of(name).orientation_references)


def reference_input(wildcards):
    """The ingested reference when the dataset has one, else nothing."""
    if not has_recording(wildcards, "reference"):
        return {}
    return {"reference": f"results/{wildcards.dataset}/ingest/reference.parquet"}


def ingest_benchmarks(name, info):
    """Run times of the ingest of every recording, and of the noise stage where it runs: the
    report's run-time table lists every rule behind it."""
    paths = [f"results/{name}/benchmarks/ingest/{r}.tsv" for r in info.recordings]
    if has_noise_recording(name):
        paths.append(f"results/{name}/benchmarks/noise.tsv")
    return paths


def noise_report_inputs(name):
    """The noise section's inputs (noise.json, then its figure) when the dataset has one."""
    if not has_noise_recording(name):
        return {}
    figure = f"results/{name}/figures/noise_allan.png"
    return {"noise": [f"results/{name}/noise.json", figure]}


def report_inputs(wildcards):
    """Artifacts, figures and run-time benchmarks of a dataset's report, by the path it took."""
    d = wildcards.dataset
    info = dataset_info(wildcards)
    inputs = {"summary": f"results/{d}/ingest/summary.json", "stages": f"results/{d}/stages.json"}
    figures = [f"results/{d}/segments/{r}.png" for r in info.recordings if r != "reference"]
    if not full_protocol(d):
        inputs.update({k: f"results/{d}/partial/{k}.json" for k in ("mag", "acc", "gyr")})
        inputs["calibration"] = f"results/{d}/partial/calibration.json"
        benchmarks = [f"results/{d}/benchmarks/{rule}.tsv" for rule in ("segment", "partial")]
        benchmarks += ingest_benchmarks(d, info)
        inputs["figure_dir"] = f"results/{d}/partial/figures"
        benchmarks.append(f"results/{d}/benchmarks/gap_diagnose_partial.tsv")
        if has_orientation_reference(d):
            inputs["validation"] = f"results/{d}/reference/validation.json"
            figures.append(f"results/{d}/figures/reference_orientation.png")
            benchmarks.append(f"results/{d}/benchmarks/validate_references.tsv")
            benchmarks += [
                f"results/{d}/benchmarks/reference/ingest_{r}.tsv"
                for r in info.orientation_references
            ]
        gap = [f"results/{d}/gap/{n}" for n in ("diagnosis.json", "gap_map.png", "effects.png")]
        noise = noise_report_inputs(d) | holdout_report_inputs(d)
        return {**inputs, "figures": figures, "benchmarks": benchmarks, "gap": gap, **noise}
    inputs.update({k: f"results/{d}/{k}.json" for k in ("mag", "acc", "gyr", "validation")})
    inputs.update(calibration=f"results/{d}/calibration.json", tables=f"results/{d}/tables.csv")
    figures += [
        f"results/{d}/figures/{name}.png"
        for name in ("mag_raw", "mag_step1", "mag_phases", "mag_step2", "acc_cube", "acc_phases")
        + ("gyr_bias", "gyr_phases")
    ]
    benchmarks = [
        f"results/{d}/benchmarks/{rule}.tsv"
        for rule in ("segment", "mag_step1", "mag_step2", "acc_cube", "acc_align")
        + ("gyr_bias", "gyr_align", "gyr_scale", "validate", "gap_diagnose", "model_terms")
        + ("lowpass/rotation3d",)
    ]
    benchmarks += ingest_benchmarks(d, info)
    if "ratetable" in info.recordings:
        figures.append(f"results/{d}/figures/gyr_table.png")
        benchmarks += [f"results/{d}/benchmarks/{r}.tsv" for r in ("gyr_table", "gyr_table_align")]
    if "reference" in info.recordings:
        figures += [
            f"results/{d}/figures/validation_magnitudes.png",
            f"results/{d}/figures/validation_xcorr.png",
        ]
    gap = [f"results/{d}/gap/{name}" for name in ("diagnosis.json", "gap_map.png", "effects.png")]
    inputs.update(terms=f"results/{d}/terms.json", gap_after=f"results/{d}/gap/after.json")
    noise = noise_report_inputs(d)
    return {**inputs, "figures": figures, "benchmarks": benchmarks, "gap": gap, **noise}


#: The checks of the diagnosis (imucal.gap.blind, .stress, .detection): their sessions are
#: planned when a check's target is asked for, not when the workflow is parsed.
@lru_cache(maxsize=None)
def check_plan(check):
    """The sealed plan of a check: one spec per session (effects, truth preset, protocol)."""
    settings = config[check]
    if check == "blind":
        from imucal.gap.blind import blind_plan

        return blind_plan(
            settings["seed"],
            settings["seeds_per_effect"],
            settings["n_null"],
            settings["unknown"],
            shapes=settings["shapes"],
        )
    if check == "stress":
        from imucal.gap.stress import stress_plan

        return stress_plan(settings["seed"], settings["seeds_alone"], settings["n_clean"])
    from imucal.gap.detection import detection_plan

    return detection_plan(
        settings["seed"],
        settings["factors"],
        settings["seeds_per_level"],
        settings["effects"] or None,
        settings["n_clean"],
    )


def check_spec(check):
    """Param function: the sealed spec of one session of a check (only its render rule)."""

    def spec(wildcards):
        for session in check_plan(check):
            if session["name"] == wildcards.session:
                return session
        raise ValueError(f"{wildcards.session!r} is not a session of the {check} check's plan")

    return spec


def check_files(check, pattern):
    """Input function: ``pattern`` for every session of a check."""

    def files(wildcards):
        return expand(pattern, session=[s["name"] for s in check_plan(check)])

    return files


def diagnosis_settings(check=None):
    """Param function: the diagnosis settings (config `gap`); a check diagnoses with its own
    number of replicas, and the blind check leaves each session's unknown effects out."""

    def settings(wildcards):
        values = dict(config["gap"])
        if check is not None:
            values["replicas"] = config[check]["replicas"]
        if check == "blind":
            from imucal.gap.blind import public_plan

            values["exclude"] = public_plan(check_plan("blind"))[wildcards.session]
        return values

    return settings


def fleet_calibrations(wildcards):
    """The calibration of every session of the fleet's sample sheet, by dataset."""
    if FLEET_SHEET is None:
        raise ValueError(
            "the fleet target needs a sample sheet: set config fleet.sessions (docs/fleet.md)"
        )
    return {name: calibration_path(name) for name in FLEET_SHEET["dataset"]}


# The Monte-Carlo check of the reported uncertainty (rules in benchmark.smk). A setting is the
# paper's protocol clean or with effects, or one partial protocol; 'partial' tables them all.
UNCERTAINTY_PARTIAL = config["uncertainty"]["partial_protocols"]


wildcard_constraints:
    setting="|".join(["clean", "effects", "partial", *UNCERTAINTY_PARTIAL]),


def uncertainty_effects(wildcards):
    """Comma-separated simulator effects of a setting ('' for clean)."""
    return ",".join(config["uncertainty"]["effects"]) if wildcards.setting == "effects" else ""


def uncertainty_protocol(wildcards):
    """The protocol of a setting: 'full' for clean and effects, else the partial protocol."""
    return "full" if wildcards.setting in ("clean", "effects") else wildcards.setting


def uncertainty_chunks(wildcards):
    """The chunk files of a setting: seeds 0 .. sessions - 1 in steps of the chunk size; for
    'partial' those of every partial protocol."""
    u = config["uncertainty"]
    settings = UNCERTAINTY_PARTIAL if wildcards.setting == "partial" else [wildcards.setting]
    return [
        f"results/uncertainty/{setting}/chunk{first}.json"
        for setting in settings
        for first in range(0, u["sessions"], u["chunk"])
    ]
