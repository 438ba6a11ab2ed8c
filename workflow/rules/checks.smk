# The checks: the sealed plans of the diagnosis's simulated checks (blind, stress, outside,
# detection) and
# the settings of the Monte-Carlo check of the reported uncertainty. No rules here.
from functools import lru_cache


#: The checks of the diagnosis (imucal.gap.blind, .stress, .outside, .detection): their sessions are
#: planned when a check's target is asked for, not when the workflow is parsed.
@lru_cache(maxsize=None)
def check_plan(check):
    """The sealed plan of a check: one spec per session (effects, truth preset, protocol)."""
    from imucal.gap.checks import check_plan as plan_of

    return plan_of(check, config[check])


def check_spec(check):
    """Param function: the sealed spec of one session of a check (only its render rule)."""

    def spec(wildcards):
        for session in check_plan(check):
            if session["name"] == wildcards.session:
                return session
        raise ValueError(f"{wildcards.session!r} is not a session of the {check} check's plan")

    return spec


def check_files(check, pattern):
    """Input function: ``pattern`` for every session of a check."""

    def files(wildcards):
        return expand(pattern, session=[s["name"] for s in check_plan(check)])

    return files


def diagnosis_settings(check=None):
    """Param function: the diagnosis settings (config `gap`); a check diagnoses with its own
    number of replicas, and the blind check leaves each session's unknown effects out."""

    def settings(wildcards):
        values = dict(config["gap"])
        if check is not None:
            values["replicas"] = config[check]["replicas"]
        if check == "blind":
            from imucal.gap.blind import public_plan

            values["exclude"] = public_plan(check_plan("blind"))[wildcards.session]
        return values

    return settings


# The Monte-Carlo check of the reported uncertainty (rules in benchmark.smk). A setting is the
# paper's protocol clean or with effects, or one partial protocol; 'partial' tables them all.
UNCERTAINTY_PARTIAL = config["uncertainty"]["partial_protocols"]


wildcard_constraints:
    setting="|".join(["clean", "effects", "partial", *UNCERTAINTY_PARTIAL]),


def uncertainty_effects(wildcards):
    """Comma-separated simulator effects of a setting ('' for clean)."""
    return ",".join(config["uncertainty"]["effects"]) if wildcards.setting == "effects" else ""


def uncertainty_protocol(wildcards):
    """The protocol of a setting: 'full' for clean and effects, else the partial protocol."""
    return "full" if wildcards.setting in ("clean", "effects") else wildcards.setting


def uncertainty_chunks(wildcards):
    """The chunk files of a setting: seeds 0 .. sessions - 1 in steps of the chunk size; for
    'partial' those of every partial protocol."""
    u = config["uncertainty"]
    settings = UNCERTAINTY_PARTIAL if wildcards.setting == "partial" else [wildcards.setting]
    return [
        f"results/uncertainty/{setting}/chunk{first}.json"
        for setting in settings
        for first in range(0, u["sessions"], u["chunk"])
    ]
