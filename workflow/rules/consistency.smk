# The shipped calibration's standard deviations checked on its own data
# (imucal.validation.consistency): the session cut into two independent parts, the same chain on
# each, the parts' difference against their stated standard deviations per sensor and group;
# results/{dataset}/consistency.json. Where a group's RMS z exceeds 1.5 the calibration the
# session ships (results/{dataset}/calibration.json, both paths) has its standard deviations
# inflated by it, with the reason and a warning.


rule consistency_partial:
    input:
        unpack(ingested_imu_all),
        segments="results/{dataset}/segments.parquet",
        dataset_yaml=dataset_yaml,
        orientation=orientation_references,
        listing="results/{dataset}/partial/stages.json",
        calibration="results/{dataset}/partial/calibration.json",
        mag="results/{dataset}/partial/mag.json",
        acc="results/{dataset}/partial/acc.json",
        gyr="results/{dataset}/partial/gyr.json",
    output:
        check="results/{dataset}/consistency.json",
    log:
        "results/{dataset}/logs/consistency.log",
    benchmark:
        "results/{dataset}/benchmarks/consistency.tsv"
    wildcard_constraints:
        dataset=datasets_pattern(full=False),
    conda:
        "../envs/imucal.yaml"
    params:
        pipeline=PIPELINE_SETTINGS,
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/consistency_partial.py"


rule consistency_full:
    input:
        unpack(ingested_imu),
        segments="results/{dataset}/segments.parquet",
        dataset_yaml=dataset_yaml,
    output:
        check="results/{dataset}/consistency.json",
    log:
        "results/{dataset}/logs/consistency.log",
    benchmark:
        "results/{dataset}/benchmarks/consistency.tsv"
    wildcard_constraints:
        dataset=datasets_pattern(full=True),
    conda:
        "../envs/imucal.yaml"
    params:
        pipeline=PIPELINE_SETTINGS,
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/consistency_full.py"


# A partial session ships its calibration at the same path as the paper's protocol.
rule calibration_partial:
    input:
        calibration="results/{dataset}/partial/calibration.json",
        check="results/{dataset}/consistency.json",
    output:
        calibration="results/{dataset}/calibration.json",
    log:
        "results/{dataset}/logs/calibration.log",
    wildcard_constraints:
        dataset=datasets_pattern(full=False),
    conda:
        "../envs/imucal.yaml"
    params:
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/calibration_partial.py"


# The table of every public recording's check (docs/real-recordings.md shows it).
rule consistency_table:
    input:
        unpack(real_consistency_checks),
    output:
        table="results/real/consistency.md",
    log:
        "results/real/logs/consistency_table.log",
    localrule: True
    conda:
        "../envs/imucal.yaml"
    params:
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/consistency_table.py"
