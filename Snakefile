# Calibration of a 9-axis IMU on a 3-D rotation platform (Zhang, Hoeflinger, Reindl 2014).
# This file only reads and validates the config, includes the stages in pipeline order and
# names the final targets; see workflow/rules/ for the stages and imucal/ for the numerics.
import sys
import time

from snakemake.exceptions import WorkflowError
from snakemake.utils import min_version, validate

from imucal.io.configfile import command_line_problem, config_problem
from imucal.modelterms.registry import settings_schema
from imucal.terms import TermSettings

min_version("8.0")
#: When this run started: the reports written since are named on its last line.
RUN_STARTED = time.time()


configfile: "config/config.yaml"


# a misspelt key or a results file read as a config: one paragraph with the file and the fix
# (snakemake's own message prints the whole schema); validate then fills in the defaults
CONFIG_PROBLEM = config_problem(
    config,
    "workflow/schemas/config.schema.yaml",
    ["config/config.yaml", *workflow.overwrite_configfiles],
    sections={"terms": settings_schema()},
)
if CONFIG_PROBLEM:
    raise WorkflowError(CONFIG_PROBLEM)
validate(config, "workflow/schemas/config.schema.yaml")
# the section `terms` is made of the registered model terms' switches and options
config["terms"] = TermSettings.from_config(config["terms"]).to_config()


include: "workflow/rules/datasets.smk"
include: "workflow/rules/inputs.smk"
include: "workflow/rules/targets.smk"
include: "workflow/rules/checks.smk"
include: "workflow/rules/ingest.smk"
include: "workflow/rules/segment.smk"
include: "workflow/rules/stages.smk"
include: "workflow/rules/calibration.smk"
include: "workflow/rules/noise.smk"
include: "workflow/rules/holdout.smk"
include: "workflow/rules/partial.smk"
include: "workflow/rules/consistency.smk"
include: "workflow/rules/reference.smk"
include: "workflow/rules/report.smk"
include: "workflow/rules/gap.smk"
include: "workflow/rules/fleet.smk"
include: "workflow/rules/benchmark.smk"


rule all:
    default_target: True
    input:
        all_targets,


rule real:
    input:
        real_targets,


# a target written after --forcerun is read as a file to rerun, and the whole workflow planned
COMMAND_PROBLEM = command_line_problem(sys.argv, [r.name for r in workflow.rules])
if COMMAND_PROBLEM:
    raise WorkflowError(COMMAND_PROBLEM)


onsuccess:
    announce_reports(RUN_STARTED)
