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
