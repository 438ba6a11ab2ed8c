# Magnetometer: step 1 the ellipsoid fit (eqs. 17-24), step 2 T_R,mag from the rotation3d
# phases (eqs. 25-27).


rule mag_step1:
    input:
        unpack(mag_step1_inputs),
    output:
        step1="results/{dataset}/mag_step1.json",
    log:
        "results/{dataset}/logs/mag_step1.log",
    benchmark:
        "results/{dataset}/benchmarks/mag_step1.tsv"
    conda:
        "../envs/imucal.yaml"
    params:
        field_norm=field_norm,
        refine_lm=FIT_METHODS["mag_refine_lm"],
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/mag_step1.py"


rule mag_step2:
    input:
        rotation3d="results/{dataset}/ingest/rotation3d.parquet",
        segments="results/{dataset}/segments.parquet",
        step1="results/{dataset}/mag_step1.json",
    output:
        mag="results/{dataset}/mag.json",
        mag_raw=report(
            "results/{dataset}/figures/mag_raw.png",
            caption="../../imucal/report/captions/mag_raw.rst",
            category="Magnetometer",
        ),
        mag_step1=report(
            "results/{dataset}/figures/mag_step1.png",
            caption="../../imucal/report/captions/mag_step1.rst",
            category="Magnetometer",
        ),
        mag_phases=report(
            "results/{dataset}/figures/mag_phases.png",
            caption="../../imucal/report/captions/mag_phases.rst",
            category="Magnetometer",
        ),
        mag_step2=report(
            "results/{dataset}/figures/mag_step2.png",
            caption="../../imucal/report/captions/mag_step2.rst",
            category="Magnetometer",
        ),
    log:
        "results/{dataset}/logs/mag_step2.log",
    benchmark:
        "results/{dataset}/benchmarks/mag_step2.tsv"
    conda:
        "../envs/imucal.yaml"
    params:
        method=FIT_METHODS["mag_alignment"],
        exact=PIPELINE_SETTINGS["exact_rotation"],
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/mag_step2.py"
