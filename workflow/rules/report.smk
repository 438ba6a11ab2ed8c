# Validation against the Xsens MTx reference (reference-free checks without one) and the HTML
# lab report.


rule validate:
    input:
        unpack(reference_input),
        rotation3d="results/{dataset}/ingest/rotation3d.parquet",
        segments="results/{dataset}/segments.parquet",
        calibration="results/{dataset}/calibration.json",
    output:
        validation=report(
            "results/{dataset}/validation.json",
            caption="../report/validation.rst",
            category="Validation",
        ),
    log:
        "results/{dataset}/logs/validate.log",
    benchmark:
        "results/{dataset}/benchmarks/validate.tsv"
    conda:
        "../envs/imucal.yaml"
    params:
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/validate.py"


rule validation_figures:
    input:
        reference="results/{dataset}/ingest/reference.parquet",
        rotation3d="results/{dataset}/ingest/rotation3d.parquet",
        calibration="results/{dataset}/calibration.json",
        validation="results/{dataset}/validation.json",
    output:
        magnitudes=report(
            "results/{dataset}/figures/validation_magnitudes.png",
            caption="../../imucal/report/captions/validation_magnitudes.rst",
            category="Validation",
        ),
        xcorr="results/{dataset}/figures/validation_xcorr.png",
    log:
        "results/{dataset}/logs/validation_figures.log",
    conda:
        "../envs/imucal.yaml"
    params:
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/validation_figures.py"


rule report:
    input:
        unpack(report_inputs),
        dataset_yaml=dataset_yaml,
    output:
        html=report(
            "reports/{dataset}.html",
            caption="../report/lab_report.rst",
            category="Lab report",
        ),
    log:
        "results/{dataset}/logs/report.log",
    benchmark:
        "results/{dataset}/benchmarks/report.tsv"
    wildcard_constraints:
        dataset=ALL_DATASETS_PATTERN,
    conda:
        "../envs/imucal.yaml"
    params:
        settings=run_settings,
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/report.py"
