# Helpers shared by the rules: the dataset table, input functions, wildcard constraints.
# No rules here.
from pathlib import Path

import imucal
from imucal.dataset import IMU_RECORDINGS, read_dataset

DATASETS = sorted(config["datasets"])
#: Package version as a param of every fit rule: an upgrade of imucal reruns them.
IMUCAL_VERSION = imucal.__version__


wildcard_constraints:
    dataset="[a-z0-9_]+",
    recording="|".join(("rotation3d", "cube", "ratetable", "static", "reference")),


def dataset_folder(wildcards):
    """Folder of a dataset, relative paths taken from the working directory."""
    return str(Path(config["datasets"][wildcards.dataset]))


def dataset_info(wildcards):
    return read_dataset(dataset_folder(wildcards))


def dataset_yaml(wildcards):
    return str(Path(dataset_folder(wildcards)) / "dataset.yaml")


def raw_recording(wildcards):
    """The raw file of one recording, as named in dataset.yaml."""
    info = dataset_info(wildcards)
    if wildcards.recording not in info.recordings:
        raise ValueError(
            f"dataset {wildcards.dataset!r} ({info.folder}/dataset.yaml) has no recording "
            f"{wildcards.recording!r}; it has {sorted(info.recordings)}"
        )
    return str(info.recordings[wildcards.recording])


def ingested(wildcards):
    """All ingested recordings of a dataset, by recording name."""
    info = dataset_info(wildcards)
    return {
        name: f"results/{wildcards.dataset}/ingest/{name}.parquet" for name in info.recordings
    }


def ingested_imu(wildcards):
    """Ingested IMU recordings (not the reference) of a dataset, by recording name."""
    info = dataset_info(wildcards)
    return {
        name: f"results/{wildcards.dataset}/ingest/{name}.parquet"
        for name in IMU_RECORDINGS
        if name in info.recordings
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


def all_targets(wildcards):
    """Final outputs of every configured dataset (read lazily, only when `all` is requested)."""
    targets = []
    for name in DATASETS:
        recordings = read_dataset(config["datasets"][name]).recordings
        targets += [f"results/{name}/ingest/summary.json", f"reports/{name}.html"]
        targets += [f"results/{name}/calibration.json", f"results/{name}/tables.csv"]
        targets += [f"results/{name}/segments/{r}.png" for r in IMU_RECORDINGS if r in recordings]
        targets += [f"results/{name}/gap/diagnosis.json"]
    return targets


def mag_step1_inputs(wildcards):
    """rotation3d, and the cube's magnetometer samples offered for coverage."""
    names = ["rotation3d"] + (["cube"] if has_recording(wildcards, "cube") else [])
    return {name: f"results/{wildcards.dataset}/ingest/{name}.parquet" for name in names}


def field_norm(wildcards):
    return dataset_info(wildcards).field_norm


def _git_commit():
    import subprocess

    try:
        out = subprocess.run(
            ["git", "rev-parse", "HEAD"], capture_output=True, text=True, check=True
        )
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return out.stdout.strip()


#: Commit of the workflow checkout, for the report's provenance.
GIT_COMMIT = _git_commit()


def reference_input(wildcards):
    """The ingested reference when the dataset has one, else nothing."""
    if not has_recording(wildcards, "reference"):
        return {}
    return {"reference": f"results/{wildcards.dataset}/ingest/reference.parquet"}


def report_inputs(wildcards):
    """Every figure of a dataset and the run-time benchmarks of its fit rules."""
    d = wildcards.dataset
    info = dataset_info(wildcards)
    figures = [f"results/{d}/figures/acc_cube.png", f"results/{d}/figures/gyr_bias.png"]
    benchmarks = [
        f"results/{d}/benchmarks/{rule}.tsv"
        for rule in ("segment", "mag_step1", "mag_step2", "acc_cube", "acc_align")
        + ("gyr_bias", "gyr_align", "gyr_scale", "validate")
    ]
    if "ratetable" in info.recordings:
        figures.append(f"results/{d}/figures/gyr_table.png")
        benchmarks += [f"results/{d}/benchmarks/gyr_table.tsv"]
    if "reference" in info.recordings:
        figures += [
            f"results/{d}/figures/validation_magnitudes.png",
            f"results/{d}/figures/validation_xcorr.png",
        ]
    figures += [
        f"results/{d}/segments/{r}.png" for r in IMU_RECORDINGS if r in info.recordings
    ]
    gap = [f"results/{d}/gap/{name}" for name in ("diagnosis.json", "gap_map.png", "effects.png")]
    return {"figures": figures, "benchmarks": benchmarks, "gap": gap}


#: The blind check's hidden plan (imucal.gap.blind); rules see only names and exclusions.
from imucal.gap.blind import blind_plan, public_plan

_BLIND = config["blind"]
_BLIND_PLAN = blind_plan(
    _BLIND["seed"], _BLIND["seeds_per_effect"], _BLIND["n_null"], _BLIND["unknown"]
)
BLIND_SESSIONS = [s["name"] for s in _BLIND_PLAN]
_BLIND_EXCLUDE = public_plan(_BLIND_PLAN)


def blind_spec(wildcards):
    """The hidden spec of one blind session (only the render rule takes it)."""
    return next(s for s in _BLIND_PLAN if s["name"] == wildcards.session)


def blind_exclude(wildcards):
    """Effects left out of the diagnosis's library for one blind session."""
    return _BLIND_EXCLUDE[wildcards.session]
