"""One list of stages: the partial path, the rules and stages.json follow the registry."""

import re
from pathlib import Path

from imucal.pipeline.partial import RUNNERS, full_protocol_stages
from imucal.pipeline.registry import FINAL, STAGES, VALIDATE, full_protocol_artifacts

REPO = Path(__file__).resolve().parents[2]


def test_the_partial_path_runs_every_registered_stage_in_order() -> None:
    assert list(RUNNERS) == list(STAGES)
    assert {s for stages in FINAL.values() for s in stages} <= set(STAGES)
    assert all(STAGES[s].sensor == sensor for sensor, stages in FINAL.items() for s in stages)


def test_every_artifact_is_written_by_the_rule_of_its_stage() -> None:
    rules = "\n".join(p.read_text() for p in (REPO / "workflow" / "rules").glob("*.smk"))
    for stage, artifact in full_protocol_artifacts().items():
        block = re.search(rf"^rule {stage}:\n(.*?)(?=^rule |\Z)", rules, re.M | re.S)
        assert block is not None, stage
        assert f'"results/{{dataset}}/{artifact}"' in block.group(1), (stage, artifact)


def test_stages_json_lists_the_registry_then_the_validation() -> None:
    rows = full_protocol_stages({"rotation3d", "cube"}, has_reference=False)
    assert [r["stage"] for r in rows] == [*STAGES, VALIDATE.name]
    assert [r["what"] for r in rows[:-1]] == [s.what for s in STAGES.values()]
