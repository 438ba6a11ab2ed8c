# The paper's calibration stages (the nodes of imucal.pipeline.graph.FULL_PROTOCOL) in run
# order: magnetometer steps 1 and 2 (eqs. 17-27), the accelerometer's cube fit (eq. 32) and
# alignment, the gyroscope's bias (eqs. 34-35), alignment (eqs. 28-31), scale without tools
# (eq. 36), rate-table fit (eq. 33) and its alignment where the dataset has a rate table, and
# `gyr`, which combines them with Tables I and II. What each reads, the settings it takes and
# the figures it writes are the node's; the in-process chain runs the same nodes. A sensor's
# stages that need the same recording run in one job, which reads the recordings once in one
# process (imucal.pipeline.jobs.STAGE_JOBS), each stage with its own artifact, figures and
# not-run record.
from imucal.pipeline.graph import source_file
from imucal.pipeline.jobs import STAGE_JOBS


def stage_inputs(job):
    """Input function of a job's rule: the files of the sources its stages read from outside
    it, for the dataset."""

    def inputs(wildcards):
        recordings = frozenset(dataset_info(wildcards).recordings)
        files = {}
        for source in job.reads(recordings):
            if source == "truth":  # a simulated or conformance dataset's truth (tables.csv)
                truth = Path(dataset_folder(wildcards)) / "truth.json"
                if truth.is_file():
                    files[source] = str(truth)
            else:
                files[source] = f"results/{wildcards.dataset}/{source_file(source)}"
        return files

    return inputs


def stage_outputs(job):
    """A job's artifacts, figures and tables; each figure and table in Snakemake's report with
    its caption."""
    captions = {(node.name, out.key): out for node in job.nodes for out in node.outputs}
    outputs = {}
    for key, (stage, kind, path) in job.files().items():
        out = captions.get((stage, kind))
        outputs[key] = f"results/{{dataset}}/{path}"
        if out is not None:
            outputs[key] = report(
                outputs[key], caption=f"../../{out.caption}", category=out.category
            )
    return outputs


def stage_settings(job):
    """Param function of a job's rule: each stage's settings (a changed one reruns it)."""

    def settings(wildcards):
        """The job's settings for the dataset by stage (imucal.pipeline.graph.SETTINGS)."""
        options = pipeline_options(wildcards)
        return {node.name: node.settings_of(options) for node in job.nodes}

    return settings


def dataset_recordings(wildcards):
    """The dataset's recordings (a param: what a node reads depends on them)."""
    return sorted(dataset_info(wildcards).recordings)


for stage_job in STAGE_JOBS.values():

    rule:
        name:
            stage_job.name
        input:
            unpack(stage_inputs(stage_job)),
        output:
            **stage_outputs(stage_job),
        log:
            f"results/{{dataset}}/logs/{stage_job.name}.log",
        benchmark:
            f"results/{{dataset}}/benchmarks/{stage_job.name}.tsv"
        conda:
            "../envs/imucal.yaml"
        params:
            settings=stage_settings(stage_job),
            recordings=dataset_recordings,
            imucal_version=IMUCAL_VERSION,
        script:
            "../scripts/stage.py"
