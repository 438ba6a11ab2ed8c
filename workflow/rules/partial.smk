# Sessions that do not follow the paper's whole protocol (public recordings, hand-held data):
# every stage the recordings allow, in one rule (imucal.pipeline.partial), and the stage listing
# results/{dataset}/stages.json of every session.


rule partial:
    input:
        unpack(ingested_imu_all),
        unpack(partial_holdout),
        segments="results/{dataset}/segments.parquet",
        dataset_yaml=dataset_yaml,
        orientation=orientation_references,
    output:
        calibration="results/{dataset}/partial/calibration.json",
        stages="results/{dataset}/partial/stages.json",
        mag="results/{dataset}/partial/mag.json",
        acc="results/{dataset}/partial/acc.json",
        gyr="results/{dataset}/partial/gyr.json",
        figures=directory("results/{dataset}/partial/figures"),
    log:
        "results/{dataset}/logs/partial.log",
    benchmark:
        "results/{dataset}/benchmarks/partial.tsv"
    conda:
        "../envs/imucal.yaml"
    params:
        pipeline=PIPELINE_SETTINGS,
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/partial.py"


rule stages_full:
    input:
        unpack(full_stage_artifacts),
        dataset_yaml=dataset_yaml,
        segments="results/{dataset}/segments.parquet",
    output:
        stages="results/{dataset}/full/stages.json",
    log:
        "results/{dataset}/logs/stages_full.log",
    # off the way to calibration.json: runs on a core the stages leave free
    priority: -1
    conda:
        "../envs/imucal.yaml"
    params:
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/stages_full.py"


rule stages:
    input:
        stages=stages_listing,
    output:
        stages=report(
            "results/{dataset}/stages.json",
            caption="../report/stages.rst",
            category="Stages",
        ),
    log:
        "results/{dataset}/logs/stages.log",
    localrule: True
    conda:
        "../envs/imucal.yaml"
    shell:
        "cp {input.stages} {output.stages} 2> {log}"
