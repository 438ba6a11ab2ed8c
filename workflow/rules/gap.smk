# Sim-to-real gap diagnosis: every dataset against its twin (imucal.gap), in the
# default run; the blind check (`snakemake --cores 2 blind`) renders sessions with hidden
# effects, keeps their answer keys under results/blind/sealed/ (an input of the scorer only)
# and scores the diagnoses; the stress set (`snakemake --cores 2 stress`) does the same with
# sessions at the harsh end of consumer MEMS parts, recording a session the pipeline or the
# diagnosis fails on as a crash; the detection sweep (`snakemake --cores 2 detection`) renders
# each library effect alone over a grid of magnitudes and scores its detection limit.


# The diagnosis runs the paper's chain in process (imucal.pipeline.full) on the ingested
# recordings and the segments: it waits for none of the fit rules and runs beside them, started
# first (priority) as the longest job on the way to calibration.json and the report.
rule gap_diagnose:
    input:
        unpack(ingested),
        dataset_yaml=dataset_yaml,
        segments="results/{dataset}/segments.parquet",
    output:
        diagnosis=report(
            "results/{dataset}/gap/diagnosis.json",
            caption="../report/gap.rst",
            category="Sim-to-real gap",
        ),
        gap_map=report(
            "results/{dataset}/gap/gap_map.png",
            caption="../report/gap.rst",
            category="Sim-to-real gap",
        ),
        effects=report(
            "results/{dataset}/gap/effects.png",
            caption="../report/gap.rst",
            category="Sim-to-real gap",
        ),
    log:
        "results/{dataset}/logs/gap_diagnose.log",
    benchmark:
        "results/{dataset}/benchmarks/gap_diagnose.tsv"
    wildcard_constraints:
        dataset=datasets_pattern(full=True),
    priority: 10
    conda:
        "../envs/imucal.yaml"
    params:
        settings=diagnosis_settings(),
        pipeline=PIPELINE_SETTINGS,
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/gap_diagnose.py"


# A session off the paper's protocol: the same diagnosis on its static recording (docs/gap-real.md);
# without one, diagnosis.json says that no location could be scored and why.
rule gap_diagnose_partial:
    input:
        unpack(gap_partial_inputs),
        dataset_yaml=dataset_yaml,
    output:
        diagnosis=report(
            "results/{dataset}/gap/diagnosis.json",
            caption="../report/gap.rst",
            category="Sim-to-real gap",
        ),
        gap_map=report(
            "results/{dataset}/gap/gap_map.png",
            caption="../report/gap.rst",
            category="Sim-to-real gap",
        ),
        effects=report(
            "results/{dataset}/gap/effects.png",
            caption="../report/gap.rst",
            category="Sim-to-real gap",
        ),
    log:
        "results/{dataset}/logs/gap_diagnose_partial.log",
    benchmark:
        "results/{dataset}/benchmarks/gap_diagnose_partial.tsv"
    wildcard_constraints:
        dataset=datasets_pattern(full=False),
    conda:
        "../envs/imucal.yaml"
    params:
        settings=diagnosis_settings(),
        windows_s=config["reference"]["windows_s"],
        poses_recording=holdout_recording_param,
        settle_s=config["temperature_holdout"]["settle_s"],
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/gap_diagnose_partial.py"


# reports/blind.html and reports/stress.html are pages of the checks, not datasets' lab reports
ruleorder: blind_score > report
ruleorder: stress_score > report
ruleorder: outside_score > report
ruleorder: detection_score > report


rule blind_render:
    output:
        folder=directory("results/blind/data/{session}"),
        key="results/blind/sealed/{session}.json",
    log:
        "results/blind/logs/render/{session}.log",
    benchmark:
        "results/blind/benchmarks/render/{session}.tsv"
    conda:
        "../envs/imucal.yaml"
    params:
        spec=check_spec("blind"),
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/gap_blind_render.py"


rule blind_diagnose:
    input:
        folder="results/blind/data/{session}",
    output:
        diagnosis="results/blind/diagnoses/{session}.json",
    log:
        "results/blind/logs/diagnose/{session}.log",
    benchmark:
        "results/blind/benchmarks/diagnose/{session}.tsv"
    conda:
        "../envs/imucal.yaml"
    params:
        settings=diagnosis_settings("blind"),
        pipeline=PIPELINE_SETTINGS,
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/gap_check_diagnose.py"


rule blind_score:
    input:
        diagnoses=check_files("blind", "results/blind/diagnoses/{session}.json"),
        sealed=check_files("blind", "results/blind/sealed/{session}.json"),
        benchmarks=check_files("blind", "results/blind/benchmarks/diagnose/{session}.tsv"),
    output:
        score="results/blind/score.json",
        html="reports/blind.html",
    log:
        "results/blind/logs/score.log",
    conda:
        "../envs/imucal.yaml"
    params:
        check="blind",
        options={},
        # read where a detection sweep has been run, not required (the page shows its limits)
        detection_score="results/detection/score.json",
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/gap_check_score.py"


rule blind:
    input:
        "results/blind/score.json",
        "reports/blind.html",


# The stress set renders with the blind check's script (the spec carries truth preset, protocol
# and effects); every check's diagnosis records a failure instead of failing the rule.
rule stress_render:
    output:
        folder=directory("results/stress/data/{session}"),
        key="results/stress/sealed/{session}.json",
    log:
        "results/stress/logs/render/{session}.log",
    benchmark:
        "results/stress/benchmarks/render/{session}.tsv"
    conda:
        "../envs/imucal.yaml"
    params:
        spec=check_spec("stress"),
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/gap_blind_render.py"


rule stress_diagnose:
    input:
        folder="results/stress/data/{session}",
    output:
        diagnosis="results/stress/diagnoses/{session}.json",
    log:
        "results/stress/logs/diagnose/{session}.log",
    benchmark:
        "results/stress/benchmarks/diagnose/{session}.tsv"
    conda:
        "../envs/imucal.yaml"
    params:
        settings=diagnosis_settings("stress"),
        pipeline=PIPELINE_SETTINGS,
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/gap_check_diagnose.py"


rule stress_score:
    input:
        diagnoses=check_files("stress", "results/stress/diagnoses/{session}.json"),
        sealed=check_files("stress", "results/stress/sealed/{session}.json"),
        benchmarks=check_files("stress", "results/stress/benchmarks/diagnose/{session}.tsv"),
    output:
        score="results/stress/score.json",
        html="reports/stress.html",
    log:
        "results/stress/logs/score.log",
    conda:
        "../envs/imucal.yaml"
    params:
        check="stress",
        options={},
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/gap_check_score.py"


rule stress:
    input:
        "results/stress/score.json",
        "reports/stress.html",


# The outside-library check renders with the blind check's script (its specs carry effects of
# the library and outside it, imucal.sim.outside).
rule outside_render:
    output:
        folder=directory("results/outside/data/{session}"),
        key="results/outside/sealed/{session}.json",
    log:
        "results/outside/logs/render/{session}.log",
    benchmark:
        "results/outside/benchmarks/render/{session}.tsv"
    conda:
        "../envs/imucal.yaml"
    params:
        spec=check_spec("outside"),
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/gap_blind_render.py"


rule outside_diagnose:
    input:
        folder="results/outside/data/{session}",
    output:
        diagnosis="results/outside/diagnoses/{session}.json",
    log:
        "results/outside/logs/diagnose/{session}.log",
    benchmark:
        "results/outside/benchmarks/diagnose/{session}.tsv"
    conda:
        "../envs/imucal.yaml"
    params:
        settings=diagnosis_settings("outside"),
        pipeline=PIPELINE_SETTINGS,
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/gap_check_diagnose.py"


rule outside_score:
    input:
        diagnoses=check_files("outside", "results/outside/diagnoses/{session}.json"),
        sealed=check_files("outside", "results/outside/sealed/{session}.json"),
        benchmarks=check_files("outside", "results/outside/benchmarks/diagnose/{session}.tsv"),
    output:
        score="results/outside/score.json",
        html="reports/outside.html",
    log:
        "results/outside/logs/score.log",
    conda:
        "../envs/imucal.yaml"
    params:
        check="outside",
        options={},
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/gap_check_score.py"


rule outside:
    input:
        "results/outside/score.json",
        "reports/outside.html",


# The detection sweep renders with the blind check's script (a crash is recorded and names
# nothing).
rule detection_render:
    output:
        folder=directory("results/detection/data/{session}"),
        key="results/detection/sealed/{session}.json",
    log:
        "results/detection/logs/render/{session}.log",
    benchmark:
        "results/detection/benchmarks/render/{session}.tsv"
    conda:
        "../envs/imucal.yaml"
    params:
        spec=check_spec("detection"),
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/gap_blind_render.py"


rule detection_diagnose:
    input:
        folder="results/detection/data/{session}",
    output:
        diagnosis="results/detection/diagnoses/{session}.json",
    log:
        "results/detection/logs/diagnose/{session}.log",
    benchmark:
        "results/detection/benchmarks/diagnose/{session}.tsv"
    conda:
        "../envs/imucal.yaml"
    params:
        settings=diagnosis_settings("detection"),
        pipeline=PIPELINE_SETTINGS,
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/gap_check_diagnose.py"


rule detection_score:
    input:
        diagnoses=check_files("detection", "results/detection/diagnoses/{session}.json"),
        sealed=check_files("detection", "results/detection/sealed/{session}.json"),
        benchmarks=check_files("detection", "results/detection/benchmarks/diagnose/{session}.tsv"),
    output:
        score="results/detection/score.json",
        html="reports/detection.html",
    log:
        "results/detection/logs/score.log",
    conda:
        "../envs/imucal.yaml"
    params:
        check="detection",
        options={
            "rate": config["detection"]["rate"],
            "confidence": config["detection"]["confidence"],
        },
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/gap_check_score.py"


rule detection:
    input:
        "results/detection/score.json",
        "reports/detection.html",


# The blind, stress and outside-library checks summed up (imucal.gap.checksummary): their
# scores and the spread effects named where they were not injected over all their sessions;
# results/checks/summary.md holds the sentences the README and docs/gap.md show.
rule gap_checks_summary:
    input:
        **{
            f"{check}_{kind}": check_files(check, f"results/{check}/{kind}/{{session}}.json")
            for check in ("blind", "stress", "outside")
            for kind in ("diagnoses", "sealed")
        },
        blind_score="results/blind/score.json",
        stress_score="results/stress/score.json",
        outside_score="results/outside/score.json",
    output:
        summary="results/checks/summary.json",
        text="results/checks/summary.md",
    log:
        "results/checks/logs/summary.log",
    localrule: True
    conda:
        "../envs/imucal.yaml"
    params:
        checks=["blind", "stress", "outside"],
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/gap_checks_summary.py"


rule gap_checks:
    input:
        "results/checks/summary.json",
        "results/checks/summary.md",
