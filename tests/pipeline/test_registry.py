"""One list of stages: the partial path, the rules and stages.json follow the registry."""

import re
import subprocess
import sys
from pathlib import Path

from imucal.pipeline.graph import FULL_PROTOCOL
from imucal.pipeline.jobs import STAGE_JOBS
from imucal.pipeline.partial import RUNNERS, full_protocol_stages
from imucal.pipeline.registry import FINAL, STAGES, VALIDATE, full_protocol_artifacts

REPO = Path(__file__).resolve().parents[2]


def test_the_partial_path_runs_every_registered_stage_in_order() -> None:
    assert list(RUNNERS) == list(STAGES)
    assert {s for stages in FINAL.values() for s in stages} <= set(STAGES)
    assert all(STAGES[s].sensor == sensor for sensor, stages in FINAL.items() for s in stages)


def test_every_node_is_in_one_job_in_run_order() -> None:
    # a sensor's stages that need the same recording, in the graph's order, and the jobs in an
    # order the graph allows: no job reads a stage of a job after it
    names = [node.name for job in STAGE_JOBS.values() for node in job.nodes]
    assert sorted(names) == sorted(FULL_PROTOCOL)
    everything = frozenset({"rotation3d", "cube", "static", "ratetable", "reference"})
    for job in STAGE_JOBS.values():
        order = [list(FULL_PROTOCOL).index(node.name) for node in job.nodes]
        assert order == sorted(order), job.name
        assert len({node.needs for node in job.nodes}) == 1, job.name
        assert {node.name.split("_")[0] for node in job.nodes} == {job.name.split("_")[0]}
    assert set(STAGE_JOBS["gyr_stages"].reads(everything)) >= {"mag_step2", "acc_align"}
    assert "gyr_table" in STAGE_JOBS["gyr_stages"].reads(everything)
    assert "gyr_table" not in STAGE_JOBS["gyr_stages"].reads(everything - {"ratetable"})


def test_every_node_is_written_by_its_jobs_rule() -> None:
    # the workflow's own dry run: the rules generated from the jobs, by name and file
    targets = [f"results/demo/{a}" for a in full_protocol_artifacts().values()]
    run = subprocess.run(
        [sys.executable, "-m", "snakemake", "--dry-run", "--forceall", "--cores", "1", *targets],
        cwd=REPO, capture_output=True, text=True, check=True,
    )  # fmt: skip
    jobs = {
        m.group(1): set(m.group(2).split(", "))
        for m in re.finditer(r"^rule (\w+):\n(?:.*\n)*?\s+output: (.*)$", run.stdout, re.M)
    }
    assert set(STAGE_JOBS) <= set(jobs)
    for job in STAGE_JOBS.values():
        written = {
            f"results/demo/{path}"
            for node in job.nodes
            for path in (node.artifact, *(out.path for out in node.outputs))
        }
        assert jobs[job.name] == written, (job.name, jobs[job.name])
    assert set(full_protocol_artifacts().items()) - {("validate", "validation.json")} <= {
        (n.name, n.artifact) for n in FULL_PROTOCOL.values()
    }


def test_stages_json_lists_the_registry_then_the_validation() -> None:
    rows = full_protocol_stages({"rotation3d", "cube"}, has_reference=False)
    assert [r["stage"] for r in rows] == [*STAGES, VALIDATE.name]
    assert [r["what"] for r in rows[:-1]] == [s.what for s in STAGES.values()]
