# The combined calibration of all three sensors in frame B (with the model terms the closed
# loop includes, its standard deviations checked on independent parts of the data:
# consistency.smk), and applying it to a recording.


# The closed loop (imucal.terms, docs/model-terms.md): per term (config `terms`) off, on, or
# auto when the diagnosis accepts its effect; the included terms are estimated, the session is
# recalibrated with them and diagnosed again (gap/after.json). The terms are estimated against
# the session's own stage artifacts (the chain is not run again for them). Without a term it
# writes the decisions only and the paper's calibration stands; with no term `auto` it does not
# wait for the diagnosis.
rule model_terms:
    input:
        unpack(ingested),
        unpack(stage_fits_for_terms),
        dataset_yaml=dataset_yaml,
        segments="results/{dataset}/segments.parquet",
        diagnosis=diagnosis_for_terms,
    output:
        terms="results/{dataset}/terms.json",
        after="results/{dataset}/gap/after.json",
    log:
        "results/{dataset}/logs/model_terms.log",
    benchmark:
        "results/{dataset}/benchmarks/model_terms.tsv"
    wildcard_constraints:
        dataset=datasets_pattern(full=True),
    conda:
        "../envs/imucal.yaml"
    params:
        terms=config["terms"],
        settings=diagnosis_settings(),
        pipeline=PIPELINE_SETTINGS,
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/model_terms.py"


rule calibration:
    input:
        acc="results/{dataset}/acc.json",
        gyr="results/{dataset}/gyr.json",
        mag="results/{dataset}/mag.json",
        terms="results/{dataset}/terms.json",
        check="results/{dataset}/consistency.json",
    output:
        calibration=report(
            "results/{dataset}/calibration.json",
            caption="../report/calibration.rst",
            category="Calibration",
        ),
    log:
        "results/{dataset}/logs/calibration.log",
    wildcard_constraints:
        dataset=datasets_pattern(full=True),
    conda:
        "../envs/imucal.yaml"
    params:
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/calibration.py"


rule apply_calibration:
    input:
        table="results/{dataset}/ingest/{recording}.parquet",
        calibration="results/{dataset}/calibration.json",
    output:
        table="results/{dataset}/calibrated/{recording}.parquet",
    log:
        "results/{dataset}/logs/apply/{recording}.log",
    conda:
        "../envs/imucal.yaml"
    params:
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/apply_calibration.py"


rule phase_figures:
    input:
        rotation3d="results/{dataset}/lowpass/rotation3d.parquet",
        segments="results/{dataset}/segments.parquet",
        acc="results/{dataset}/acc.json",
        gyr="results/{dataset}/gyr.json",
    output:
        acc=report(
            "results/{dataset}/figures/acc_phases.png",
            caption="../../imucal/report/captions/acc_phases.rst",
            category="Accelerometer",
        ),
        gyr=report(
            "results/{dataset}/figures/gyr_phases.png",
            caption="../../imucal/report/captions/gyr_phases.rst",
            category="Gyroscope",
        ),
    log:
        "results/{dataset}/logs/phase_figures.log",
    # off the way to calibration.json: runs on a core the stages leave free
    priority: -1
    conda:
        "../envs/imucal.yaml"
    params:
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/phase_figures.py"
