# The paper's calibration stages, one rule per node of imucal.pipeline.graph.FULL_PROTOCOL, in
# run order: magnetometer steps 1 and 2 (eqs. 17-27), the accelerometer's cube fit (eq. 32) and
# alignment, the gyroscope's bias (eqs. 34-35), alignment (eqs. 28-31), scale without tools
# (eq. 36), rate-table fit (eq. 33) and its alignment where the dataset has a rate table, and
# `gyr`, which combines them with Tables I and II. What each reads, the settings it takes and
# the figures it writes are the node's; the in-process chain runs the same nodes.
from imucal.pipeline.graph import FULL_PROTOCOL, source_file


def stage_inputs(node):
    """Input function of a node's rule: the files of its sources for the dataset."""

    def inputs(wildcards):
        recordings = frozenset(dataset_info(wildcards).recordings)
        files = {}
        for argument, source in node.reads(recordings).items():
            if source == "truth":  # a simulated or conformance dataset's truth (tables.csv)
                truth = Path(dataset_folder(wildcards)) / "truth.json"
                if truth.is_file():
                    files[argument] = str(truth)
            else:
                files[argument] = f"results/{wildcards.dataset}/{source_file(source)}"
        return files

    return inputs


def stage_outputs(node):
    """A node's figures and tables, each in Snakemake's report with its caption."""
    return {
        out.key: report(
            f"results/{{dataset}}/{out.path}",
            caption=f"../../{out.caption}",
            category=out.category,
        )
        for out in node.outputs
    }


def stage_settings(node):
    """Param function of a node's rule: the settings it takes (a changed one reruns it)."""

    def settings(wildcards):
        """The node's settings for the dataset (imucal.pipeline.graph.SETTINGS)."""
        return node.settings_of(pipeline_options(wildcards))

    return settings


def dataset_recordings(wildcards):
    """The dataset's recordings (a param: what a node reads depends on them)."""
    return sorted(dataset_info(wildcards).recordings)


for stage_node in FULL_PROTOCOL.values():

    rule:
        name:
            stage_node.name
        input:
            unpack(stage_inputs(stage_node)),
        output:
            **stage_outputs(stage_node),
            artifact=f"results/{{dataset}}/{stage_node.artifact}",
        log:
            f"results/{{dataset}}/logs/{stage_node.name}.log",
        benchmark:
            f"results/{{dataset}}/benchmarks/{stage_node.name}.tsv"
        conda:
            "../envs/imucal.yaml"
        params:
            settings=stage_settings(stage_node),
            recordings=dataset_recordings,
            imucal_version=IMUCAL_VERSION,
        script:
            "../scripts/stage.py"
