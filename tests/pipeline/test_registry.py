"""One list of stages: the partial path, the rules and stages.json follow the registry."""

import re
import subprocess
import sys
from pathlib import Path

from imucal.pipeline.graph import FULL_PROTOCOL
from imucal.pipeline.partial import RUNNERS, full_protocol_stages
from imucal.pipeline.registry import FINAL, STAGES, VALIDATE, full_protocol_artifacts

REPO = Path(__file__).resolve().parents[2]


def test_the_partial_path_runs_every_registered_stage_in_order() -> None:
    assert list(RUNNERS) == list(STAGES)
    assert {s for stages in FINAL.values() for s in stages} <= set(STAGES)
    assert all(STAGES[s].sensor == sensor for sensor, stages in FINAL.items() for s in stages)


def test_every_node_is_a_rule_that_writes_its_artifact_and_outputs() -> None:
    # the workflow's own dry run: the rules generated from the graph, by name and file
    targets = [f"results/demo/{a}" for a in full_protocol_artifacts().values()]
    run = subprocess.run(
        [sys.executable, "-m", "snakemake", "--dry-run", "--forceall", "--cores", "1", *targets],
        cwd=REPO, capture_output=True, text=True, check=True,
    )  # fmt: skip
    jobs = {
        m.group(1): set(m.group(2).split(", "))
        for m in re.finditer(r"^rule (\w+):\n(?:.*\n)*?\s+output: (.*)$", run.stdout, re.M)
    }
    for node in FULL_PROTOCOL.values():
        written = {f"results/demo/{node.artifact}"} | {
            f"results/demo/{out.path}" for out in node.outputs
        }
        assert jobs.get(node.name) == written, (node.name, jobs.get(node.name))
    assert set(full_protocol_artifacts().items()) - {("validate", "validation.json")} <= {
        (n.name, n.artifact) for n in FULL_PROTOCOL.values()
    }


def test_stages_json_lists_the_registry_then_the_validation() -> None:
    rows = full_protocol_stages({"rotation3d", "cube"}, has_reference=False)
    assert [r["stage"] for r in rows] == [*STAGES, VALIDATE.name]
    assert [r["what"] for r in rows[:-1]] == [s.what for s in STAGES.values()]
