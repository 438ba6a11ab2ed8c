# Calibration of a 9-axis IMU on a 3-D rotation platform (Zhang, Hoeflinger, Reindl 2014).
# This file only reads and validates the config, includes the stages in pipeline order and
# names the final targets; see workflow/rules/ for the stages and imucal/ for the numerics.
from snakemake.utils import min_version, validate

from imucal.terms import TermSettings

min_version("8.0")


configfile: "config/config.yaml"


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
