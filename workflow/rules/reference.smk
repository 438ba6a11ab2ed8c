# Orientation references (motion capture, robot) declared on recordings in dataset.yaml: each is
# ingested to unit quaternions, the partial rule fits the gyroscope against them (stage
# gyr_reference), and the session's calibration is validated against every one of them
# (imucal.pipeline.reference), held-out recordings included.


rule ingest_orientation:
    input:
        raw=orientation_files,
        dataset_yaml=dataset_yaml,
    output:
        table="results/{dataset}/reference/{recording}.parquet",
    log:
        "results/{dataset}/logs/reference/ingest_{recording}.log",
    benchmark:
        "results/{dataset}/benchmarks/reference/ingest_{recording}.tsv"
    conda:
        "../envs/imucal.yaml"
    params:
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/ingest_orientation.py"


rule validate_references:
    input:
        unpack(orientation_recordings),
        orientation=orientation_references,
        segments="results/{dataset}/segments.parquet",
        calibration="results/{dataset}/partial/calibration.json",
        gyr="results/{dataset}/partial/gyr.json",
        dataset_yaml=dataset_yaml,
    output:
        validation="results/{dataset}/reference/validation.json",
        figure="results/{dataset}/figures/reference_orientation.png",
    log:
        "results/{dataset}/logs/reference/validate.log",
    benchmark:
        "results/{dataset}/benchmarks/validate_references.tsv"
    conda:
        "../envs/imucal.yaml"
    params:
        windows_s=config["reference"]["windows_s"],
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/validate_references.py"
