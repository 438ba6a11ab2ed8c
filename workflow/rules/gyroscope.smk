# Gyroscope: bias (eqs. 34-35), T_R,gyr (eqs. 28-31), scale without tools (eq. 36, which refits
# T_R,gyr at that scale), and with a rate table (eq. 33) when the dataset has one; `gyr` combines
# them with Tables I and II.


rule gyr_bias:
    input:
        unpack(gyr_bias_inputs),
        segments="results/{dataset}/segments.parquet",
    output:
        bias="results/{dataset}/gyr_bias.json",
        figure=report(
            "results/{dataset}/figures/gyr_bias.png",
            caption="../../imucal/report/captions/gyr_bias.rst",
            category="Gyroscope",
        ),
    log:
        "results/{dataset}/logs/gyr_bias.log",
    benchmark:
        "results/{dataset}/benchmarks/gyr_bias.tsv"
    conda:
        "../envs/imucal.yaml"
    params:
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/gyr_bias.py"


rule gyr_align:
    input:
        rotation3d="results/{dataset}/lowpass/rotation3d.parquet",
        segments="results/{dataset}/segments.parquet",
        bias="results/{dataset}/gyr_bias.json",
    output:
        alignment="results/{dataset}/gyr_align.json",
    log:
        "results/{dataset}/logs/gyr_align.log",
    benchmark:
        "results/{dataset}/benchmarks/gyr_align.tsv"
    conda:
        "../envs/imucal.yaml"
    params:
        bias_estimator=FIT_METHODS["gyr_bias_estimator"],
        method=FIT_METHODS["gyr_alignment"],
        exact=PIPELINE_SETTINGS["exact_rotation"],
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/gyr_align.py"


rule gyr_scale:
    input:
        rotation3d="results/{dataset}/ingest/rotation3d.parquet",
        lowpass="results/{dataset}/lowpass/rotation3d.parquet",
        segments="results/{dataset}/segments.parquet",
        bias="results/{dataset}/gyr_bias.json",
        alignment="results/{dataset}/gyr_align.json",
        acc="results/{dataset}/acc.json",
        mag="results/{dataset}/mag.json",
    output:
        scale="results/{dataset}/gyr_scale.json",
    log:
        "results/{dataset}/logs/gyr_scale.log",
    benchmark:
        "results/{dataset}/benchmarks/gyr_scale.tsv"
    conda:
        "../envs/imucal.yaml"
    params:
        bias_estimator=FIT_METHODS["gyr_bias_estimator"],
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/gyr_scale.py"


rule gyr_table:
    input:
        ratetable="results/{dataset}/ingest/ratetable.parquet",
        segments="results/{dataset}/segments.parquet",
    output:
        fit="results/{dataset}/gyr_table.json",
        figure=report(
            "results/{dataset}/figures/gyr_table.png",
            caption="../../imucal/report/captions/gyr_table.rst",
            category="Gyroscope",
        ),
    log:
        "results/{dataset}/logs/gyr_table.log",
    benchmark:
        "results/{dataset}/benchmarks/gyr_table.tsv"
    conda:
        "../envs/imucal.yaml"
    params:
        saturation_limit_rad_s=saturation_limit("gyr"),
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/gyr_table.py"


rule gyr_table_align:
    input:
        rotation3d="results/{dataset}/lowpass/rotation3d.parquet",
        segments="results/{dataset}/segments.parquet",
        fit="results/{dataset}/gyr_table.json",
    output:
        alignment="results/{dataset}/gyr_table_align.json",
    log:
        "results/{dataset}/logs/gyr_table_align.log",
    benchmark:
        "results/{dataset}/benchmarks/gyr_table_align.tsv"
    conda:
        "../envs/imucal.yaml"
    params:
        method=FIT_METHODS["gyr_alignment"],
        exact=PIPELINE_SETTINGS["exact_rotation"],
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/gyr_table_align.py"


rule gyr:
    input:
        unpack(gyr_table_inputs),
        unpack(truth_input),
        bias="results/{dataset}/gyr_bias.json",
        scale="results/{dataset}/gyr_scale.json",
    output:
        gyr="results/{dataset}/gyr.json",
        tables=report(
            "results/{dataset}/tables.csv",
            caption="../report/tables.rst",
            category="Gyroscope",
        ),
    log:
        "results/{dataset}/logs/gyr.log",
    conda:
        "../envs/imucal.yaml"
    params:
        bias_estimator=FIT_METHODS["gyr_bias_estimator"],
        exact=PIPELINE_SETTINGS["exact_rotation"],
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/gyr.py"
