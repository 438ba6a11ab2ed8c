# Temperature terms held out across the declared static poses of a recording with a
# temperature channel (imucal.terms.poseholdout): per pose, sensor and axis, the held-out
# residual with no term, with the project's term (order chosen on the fit poses alone) and with a
# pooled linear regression, each with its uncertainty over
# blocks of hours.


rule temperature_holdout:
    input:
        recording=holdout_input,
        segments="results/{dataset}/segments.parquet",
    output:
        holdout="results/{dataset}/temperature_holdout.json",
    log:
        "results/{dataset}/logs/temperature_holdout.log",
    benchmark:
        "results/{dataset}/benchmarks/temperature_holdout.tsv"
    conda:
        "../envs/imucal.yaml"
    params:
        recording=holdout_recording_param,
        block_s=config["temperature_holdout"]["block_s"],
        settle_s=config["temperature_holdout"]["settle_s"],
        se_block_s=config["temperature_holdout"]["se_block_s"],
        max_order=config["terms"]["temperature_max_order"],
        margin_c=config["terms"]["temperature_margin_c"],
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/temperature_holdout.py"
