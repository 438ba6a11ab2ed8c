# Input functions of the stage rules: which files a rule reads for a dataset, by the path the
# session takes and the recordings it has. No rules here.
from pathlib import Path

from imucal.constants import IMU_RECORDINGS
from imucal.pipeline.graph import FULL_PROTOCOL
from imucal.pipeline.registry import full_protocol_artifacts
from imucal.terms import TermSettings


def diagnosis_for_terms(wildcards):
    """The session's diagnosis when a model term is 'auto' (the loop decides on it), else none."""
    if TermSettings.from_config(config["terms"]).needs_diagnosis:
        return f"results/{wildcards.dataset}/gap/diagnosis.json"
    return []


def stage_fits_for_terms(wildcards):
    """The session's stage artifacts when a term may be estimated (the closed loop estimates
    against them instead of running the chain again), else none."""
    if not TermSettings.from_config(config["terms"]).wanted():
        return {}
    d = wildcards.dataset
    recordings = frozenset(dataset_info(wildcards).recordings)
    return {
        f"fit_{node.name}": f"results/{d}/{node.artifact}"
        for node in FULL_PROTOCOL.values()
        if node.applies(recordings)
    }


def gap_partial_scope(wildcards):
    """Which parts of a partial session the gap diagnosis scores (imucal.gap.composite.partial_scope)."""
    # imported here: the diagnosis's imports cost the parse of every workflow about 1 s
    from imucal.gap.composite import partial_scope

    return partial_scope(
        static=has_recording(wildcards, "static"),
        references=bool(dataset_info(wildcards).orientation_references),
        poses=holdout_recording(wildcards.dataset) is not None,
    )


def gap_partial_inputs(wildcards):
    """A partial session's calibration, the ingest's summary (the clipped samples of every
    recording) and the recordings of its diagnosis's scope (gap_partial_scope): its static
    recording, its recordings with an orientation reference (with the references and the
    segments), its declared static poses with a temperature channel, or all its recordings
    and segments, whose rests are scored."""
    d = wildcards.dataset
    scope = gap_partial_scope(wildcards)
    inputs = {
        "calibration": f"results/{d}/partial/calibration.json",
        "summary": f"results/{d}/ingest/summary.json",
    }
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


def noise_input(wildcards):
    recording = noise_settings(wildcards.dataset)["recording"]
    return {"recording": f"results/{wildcards.dataset}/ingest/{recording}.parquet"}


def calibration_of(wildcards):
    """Input function: the dataset's calibration.json (:func:`calibration_path`)."""
    return calibration_path(wildcards.dataset)


def holdout_recording_param(wildcards):
    """The name of the recording of the temperature hold-out (a rule param)."""
    return holdout_recording(wildcards.dataset)


def holdout_input(wildcards):
    """The ingested recording of the temperature hold-out."""
    return f"results/{wildcards.dataset}/ingest/{holdout_recording(wildcards.dataset)}.parquet"


def partial_holdout(wildcards):
    """The temperature hold-out whose terms a partial session's calibration carries, if any."""
    if holdout_recording(wildcards.dataset) is None:
        return {}
    return {"temperature_holdout": f"results/{wildcards.dataset}/temperature_holdout.json"}


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


def reference_input(wildcards):
    """The ingested reference when the dataset has one, else nothing."""
    if not has_recording(wildcards, "reference"):
        return {}
    return {"reference": f"results/{wildcards.dataset}/ingest/reference.parquet"}
