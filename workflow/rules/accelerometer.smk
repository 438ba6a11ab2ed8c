# Accelerometer: step 1 the cube fit (eq. 32), step 2 T_R,acc from the filtered rotation3d phases.


rule acc_cube:
    input:
        cube="results/{dataset}/ingest/cube.parquet",
        segments="results/{dataset}/segments.parquet",
    output:
        fit="results/{dataset}/acc_cube.json",
        figure=report(
            "results/{dataset}/figures/acc_cube.png",
            caption="../../imucal/report/captions/acc_cube.rst",
            category="Accelerometer",
        ),
    log:
        "results/{dataset}/logs/acc_cube.log",
    benchmark:
        "results/{dataset}/benchmarks/acc_cube.tsv"
    conda:
        "../envs/imucal.yaml"
    params:
        gravity_m_s2=gravity,
        saturation_limit_m_s2=saturation_limit("acc"),
        method=FIT_METHODS["acc_cube"],
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/acc_cube.py"


rule acc_align:
    input:
        rotation3d="results/{dataset}/lowpass/rotation3d.parquet",
        segments="results/{dataset}/segments.parquet",
        fit="results/{dataset}/acc_cube.json",
    output:
        acc="results/{dataset}/acc.json",
    log:
        "results/{dataset}/logs/acc_align.log",
    benchmark:
        "results/{dataset}/benchmarks/acc_align.tsv"
    conda:
        "../envs/imucal.yaml"
    params:
        method=FIT_METHODS["acc_alignment"],
        exact=PIPELINE_SETTINGS["exact_rotation"],
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/acc_align.py"
