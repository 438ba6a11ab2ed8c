# Stage 2: low-pass filter and segmentation. The low-pass runs per recording (zero-phase
# Butterworth per contiguous block, imucal.segments.filtering); the segmentation finds the static
# intervals, rotation3d phases, cube positions and rate-table runs of a dataset in one table
# (imucal.segments.segmentation, or the manual `segments:` of dataset.yaml), plotted per recording.


rule lowpass:
    input:
        table="results/{dataset}/ingest/{recording}.parquet",
    output:
        table="results/{dataset}/lowpass/{recording}.parquet",
    log:
        "results/{dataset}/logs/lowpass/{recording}.log",
    benchmark:
        "results/{dataset}/benchmarks/lowpass/{recording}.tsv"
    conda:
        "../envs/imucal.yaml"
    params:
        order=PIPELINE_SETTINGS["lowpass_order"],
        cutoff_hz=PIPELINE_SETTINGS["lowpass_cutoff_hz"],
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/lowpass.py"


rule segment:
    input:
        unpack(ingested_imu_all),
        dataset_yaml=dataset_yaml,
    output:
        segments="results/{dataset}/segments.parquet",
    log:
        "results/{dataset}/logs/segment.log",
    benchmark:
        "results/{dataset}/benchmarks/segment.tsv"
    priority: 10
    conda:
        "../envs/imucal.yaml"
    params:
        settings=segmentation_settings,
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/segment.py"


rule plot_segments:
    input:
        table="results/{dataset}/ingest/{recording}.parquet",
        segments=rules.segment.output.segments,
    output:
        png="results/{dataset}/segments/{recording}.png",
    log:
        "results/{dataset}/logs/segments/{recording}.log",
    # off the way to calibration.json: runs on a core the stages leave free
    priority: -1
    conda:
        "../envs/imucal.yaml"
    params:
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/plot_segments.py"
