# The combined calibration of all three sensors in frame B, and applying it to a recording.


rule calibration:
    input:
        acc="results/{dataset}/acc.json",
        gyr="results/{dataset}/gyr.json",
        mag="results/{dataset}/mag.json",
    output:
        calibration=report(
            "results/{dataset}/calibration.json",
            caption="../report/calibration.rst",
            category="Calibration",
        ),
    log:
        "results/{dataset}/logs/calibration.log",
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
            caption="../report/phases.rst",
            category="Accelerometer",
        ),
        gyr=report(
            "results/{dataset}/figures/gyr_phases.png",
            caption="../report/phases.rst",
            category="Gyroscope",
        ),
    log:
        "results/{dataset}/logs/phase_figures.log",
    conda:
        "../envs/imucal.yaml"
    params:
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/phase_figures.py"
