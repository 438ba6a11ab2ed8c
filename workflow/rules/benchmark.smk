# The Monte-Carlo check of the reported uncertainty (targets `uncertainty_benchmark` and
# `uncertainty_partial`, not in the default run; docs/uncertainty.md): simulated sessions in
# chunks, then the z-score tables.


rule uncertainty_chunk:
    output:
        "results/uncertainty/{setting}/chunk{first}.json",
    log:
        "results/uncertainty/logs/{setting}/chunk{first}.log",
    conda:
        "../envs/imucal.yaml"
    params:
        per_chunk=config["uncertainty"]["chunk"],
        effects=uncertainty_effects,
        protocol=uncertainty_protocol,
        imucal_version=IMUCAL_VERSION,
    shell:
        "python tests/benchmarks/mc_uncertainty.py run --first {wildcards.first} "
        "--count {params.per_chunk} --protocol {params.protocol} "
        "--effects '{params.effects}' --out {output} > {log} 2>&1"


rule uncertainty_table:
    input:
        uncertainty_chunks,
    output:
        "results/uncertainty/{setting}/table.md",
    log:
        "results/uncertainty/logs/{setting}/table.log",
    conda:
        "../envs/imucal.yaml"
    shell:
        "python tests/benchmarks/mc_uncertainty.py table {input} --out {output} > {log} 2>&1"


rule uncertainty_benchmark:
    input:
        expand("results/uncertainty/{setting}/table.md", setting=("clean", "effects")),


rule uncertainty_partial:
    input:
        "results/uncertainty/partial/table.md",
