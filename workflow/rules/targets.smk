# What a run produces: each dataset's final targets, its report's inputs and the fleet's
# calibrations, and the line that names the reports a run wrote. No rules here.
import atexit
import sys
from imucal.export.formats import FORMATS as EXPORT_FORMATS
from imucal.pipeline.graph import FULL_PROTOCOL
from imucal.pipeline.jobs import STAGE_JOBS

EXPORT_FILES = [f"{fmt}/{name}" for fmt, names in EXPORT_FORMATS.items() for name in names]


def noise_targets(name):
    """noise.json, its figure and the exports of a dataset with a static recording."""
    if not has_noise_recording(name):
        return []
    exports = [f"results/{name}/export/{f}" for f in EXPORT_FILES]
    return [f"results/{name}/noise.json", *exports]


def holdout_report_inputs(name):
    """The temperature hold-out section's input when the dataset has one."""
    if holdout_recording(name) is None:
        return {}
    return {"temperature_holdout": f"results/{name}/temperature_holdout.json"}


def dataset_targets(name):
    """Final outputs of one dataset: its report, calibration, stage listing and plots."""
    recordings = dataset_of(name).recordings
    targets = [f"results/{name}/ingest/summary.json", f"reports/{name}.html"]
    targets += [f"results/{name}/stages.json"]
    targets += [f"results/{name}/calibration.json", f"results/{name}/gap/diagnosis.json"]
    if full_protocol(name):
        targets += [f"results/{name}/tables.csv"]
    else:
        if has_orientation_reference(name):
            targets += [f"results/{name}/reference/validation.json"]
    targets += [f"results/{name}/segments/{r}.png" for r in recordings if r != "reference"]
    targets += noise_targets(name)
    targets += list(holdout_report_inputs(name).values())
    return targets


def all_targets(wildcards):
    """Final outputs of every configured dataset (read lazily, only when `all` is requested)."""
    return [t for name in DATASETS for t in dataset_targets(name)]


def real_targets(wildcards):
    """Final outputs of every public recording of config/real, and the table of their checks
    of the standard deviations."""
    if not REAL_DATASETS:
        raise ValueError("config/real holds no dataset configs")
    targets = [t for name in sorted(REAL_DATASETS) for t in dataset_targets(name)]
    return targets + ["results/real/consistency.md"]


def real_consistency_checks(wildcards):
    """consistency.json of every public recording, by dataset."""
    return {name: f"results/{name}/consistency.json" for name in sorted(REAL_DATASETS)}


def ingest_benchmarks(name, info):
    """Run times of the ingest of every recording, and of the noise stage where it runs: the
    report's run-time table lists every rule behind it."""
    paths = [f"results/{name}/benchmarks/ingest/{r}.tsv" for r in info.recordings]
    if has_noise_recording(name):
        paths.append(f"results/{name}/benchmarks/noise.tsv")
    return paths


def noise_report_inputs(name):
    """The noise section's inputs (noise.json, then its figure) when the dataset has one."""
    if not has_noise_recording(name):
        return {}
    figure = f"results/{name}/figures/noise_allan.png"
    return {"noise": [f"results/{name}/noise.json", figure]}


def stage_report_files(d, info):
    """Figures and run-time benchmarks of the paper's stages that apply to a dataset, in run
    order (imucal.pipeline.graph)."""
    recordings = frozenset(info.recordings)
    nodes = [node for node in FULL_PROTOCOL.values() if node.applies(recordings)]
    figures = [
        f"results/{d}/{out.path}"
        for node in nodes
        for out in node.outputs
        if out.path.endswith(".png")
    ]
    jobs = [job.name for job in STAGE_JOBS.values() if job.applies(recordings)]
    return figures, [f"results/{d}/benchmarks/{name}.tsv" for name in jobs]


def rule_log(rule_name, **wildcards):
    """The log file of a rule for the given wildcards (its log pattern filled in)."""
    return getattr(rules, rule_name).log[0].format(**wildcards)


def report_logs(d, info):
    """The log of every rule behind a dataset's report (the report lists their warnings)."""
    recordings = [r for r in info.recordings if r != "reference"]
    logs = [rule_log("ingest", dataset=d, recording=r) for r in info.recordings]
    logs += [rule_log(name, dataset=d) for name in ("ingest_summary", "segment", "stages")]
    logs += [rule_log("plot_segments", dataset=d, recording=r) for r in recordings]
    if has_noise_recording(d):
        logs += [rule_log(name, dataset=d) for name in ("noise", "export")]
    if not full_protocol(d):
        logs += [
            rule_log(name, dataset=d)
            for name in ("partial", "gap_diagnose_partial", "consistency_partial")
        ]
        logs.append(rule_log("calibration_partial", dataset=d))
        if has_orientation_reference(d):
            logs += [
                rule_log("ingest_orientation", dataset=d, recording=r)
                for r in info.orientation_references
            ]
            logs.append(rule_log("validate_references", dataset=d))
        if holdout_recording(d) is not None:
            logs.append(rule_log("temperature_holdout", dataset=d))
        return logs
    jobs = [j.name for j in STAGE_JOBS.values() if j.applies(frozenset(info.recordings))]
    logs += [rule_log(name, dataset=d) for name in jobs]
    logs.append(rule_log("lowpass", dataset=d, recording="rotation3d"))
    logs += [
        rule_log(name, dataset=d)
        for name in (
            "calibration", "phase_figures", "validate", "gap_diagnose", "model_terms",
            "consistency_full",
        )
    ]  # fmt: skip
    logs.append(rule_log("stages_full", dataset=d))
    if "reference" in info.recordings:
        logs.append(rule_log("validation_figures", dataset=d))
    return logs


def report_inputs(wildcards):
    """Artifacts, figures and run-time benchmarks of a dataset's report, by the path it took."""
    d = wildcards.dataset
    info = dataset_info(wildcards)
    inputs = {"summary": f"results/{d}/ingest/summary.json", "stages": f"results/{d}/stages.json"}
    inputs["calibration"] = f"results/{d}/calibration.json"
    inputs["consistency"] = f"results/{d}/consistency.json"
    figures = [f"results/{d}/segments/{r}.png" for r in info.recordings if r != "reference"]
    if not full_protocol(d):
        inputs.update({k: f"results/{d}/partial/{k}.json" for k in ("mag", "acc", "gyr")})
        benchmarks = [
            f"results/{d}/benchmarks/{rule}.tsv" for rule in ("segment", "partial", "consistency")
        ]
        benchmarks += ingest_benchmarks(d, info)
        inputs["figure_dir"] = f"results/{d}/partial/figures"
        benchmarks.append(f"results/{d}/benchmarks/gap_diagnose_partial.tsv")
        if has_orientation_reference(d):
            inputs["validation"] = f"results/{d}/reference/validation.json"
            figures.append(f"results/{d}/figures/reference_orientation.png")
            benchmarks.append(f"results/{d}/benchmarks/validate_references.tsv")
            benchmarks += [
                f"results/{d}/benchmarks/reference/ingest_{r}.tsv"
                for r in info.orientation_references
            ]
        gap = [f"results/{d}/gap/{n}" for n in ("diagnosis.json", "gap_map.png", "effects.png")]
        noise = noise_report_inputs(d) | holdout_report_inputs(d)
        logs = report_logs(d, info)
        return {**inputs, "figures": figures, "benchmarks": benchmarks, "gap": gap, **noise,
                "logs": logs}  # fmt: skip
    inputs.update({k: f"results/{d}/{k}.json" for k in ("mag", "acc", "gyr", "validation")})
    inputs.update(tables=f"results/{d}/tables.csv")
    stage_figures, stage_benchmarks = stage_report_files(d, info)
    figures += stage_figures + [
        f"results/{d}/figures/{n}.png" for n in ("acc_phases", "gyr_phases")
    ]
    benchmarks = [
        f"results/{d}/benchmarks/{rule}.tsv" for rule in ("segment", "lowpass/rotation3d")
    ]
    benchmarks += stage_benchmarks + [
        f"results/{d}/benchmarks/{rule}.tsv"
        for rule in ("validate", "gap_diagnose", "model_terms", "consistency")
    ]
    benchmarks += ingest_benchmarks(d, info)
    if "reference" in info.recordings:
        figures += [
            f"results/{d}/figures/validation_magnitudes.png",
            f"results/{d}/figures/validation_xcorr.png",
        ]
    gap = [f"results/{d}/gap/{name}" for name in ("diagnosis.json", "gap_map.png", "effects.png")]
    inputs.update(terms=f"results/{d}/terms.json", gap_after=f"results/{d}/gap/after.json")
    noise = noise_report_inputs(d)
    logs = report_logs(d, info)
    return {**inputs, "figures": figures, "benchmarks": benchmarks, "gap": gap, **noise,
            "logs": logs}  # fmt: skip


def fleet_calibrations(wildcards):
    """The calibration of every session of the fleet's sample sheet, by dataset."""
    if FLEET_SHEET is None:
        raise ValueError(
            "the fleet target needs a sample sheet: set config fleet.sessions (docs/fleet.md)"
        )
    return {name: calibration_path(name) for name in FLEET_SHEET["dataset"]}


def reports_written(since):
    """The lab reports written since a time (s since the epoch), by name."""
    return sorted(str(p) for p in Path("reports").glob("*.html") if p.stat().st_mtime >= since)


def print_reports(since):
    """Name the lab reports a run wrote (the run's last line)."""
    written = reports_written(since)
    if written:
        which = "Lab report" if len(written) == 1 else "Lab reports"
        print(f"{which} written: {', '.join(written)} (open in a browser)", file=sys.stderr)
    else:
        print(
            "No lab report was written in this run; a dataset's report is the target "
            "reports/NAME.html",
            file=sys.stderr,
        )


def announce_reports(since):
    """At the end of a successful run, after Snakemake's own lines, name its reports."""
    atexit.register(print_reports, since)
