# Stage 1: ingest. Each raw recording (IMU CSV in counts, the MT Manager export of the
# reference, or a recording declared with a reader in dataset.yaml: every file it reads is an
# input) is read, checked and converted to SI units; then one summary per dataset.


rule ingest:
    input:
        raw=raw_recording,
        dataset_yaml=dataset_yaml,
    output:
        table="results/{dataset}/ingest/{recording}.parquet",
    log:
        "results/{dataset}/logs/ingest/{recording}.log",
    benchmark:
        "results/{dataset}/benchmarks/ingest/{recording}.tsv"
    # ingest and segment lead to the gap diagnosis, the longest job (gap.smk): they go first
    priority: 10
    conda:
        "../envs/imucal.yaml"
    params:
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/ingest.py"


rule ingest_summary:
    input:
        unpack(ingested),
    output:
        summary="results/{dataset}/ingest/summary.json",
    log:
        "results/{dataset}/logs/ingest/summary.log",
    # off the way to calibration.json: runs on a core the stages leave free
    priority: -1
    conda:
        "../envs/imucal.yaml"
    params:
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/ingest_summary.py"
