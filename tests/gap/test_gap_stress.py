"""The stress set (imucal.gap.stress): its plan, the crash-tolerant diagnosis, the scorer."""

from __future__ import annotations

import json

import numpy as np
import pytest

from imucal.gap import DiagnosisSettings
from imucal.gap.blind import SHAPES, failed_diagnosis, render_blind_session, spec_effects
from imucal.gap.checks import diagnose_folder
from imucal.gap.stress import (
    CONDITIONS,
    HARSH,
    REALISTIC_EFFECTS,
    score_stress,
    stress_plan,
)

ITEMS = list(CONDITIONS) + list(HARSH)


@pytest.fixture(scope="module")
def plan():
    return stress_plan(7, 2, 2)


def test_plan_is_deterministic_and_covers_every_item_alone_and_in_a_pair(plan):
    assert plan == stress_plan(7, 2, 2)
    assert [s["items"] for s in plan] != [s["items"] for s in stress_plan(8, 2, 2)]
    assert len(plan) >= 40
    assert [s["name"] for s in plan] == [f"s{i:02d}" for i in range(len(plan))]
    assert len({s["seed"] for s in plan}) == len(plan)
    alone = [s["items"][0] for s in plan if len(s["items"]) == 1]
    paired = [i for s in plan if len(s["items"]) == 2 for i in s["items"]]
    for item in ITEMS:
        assert alone.count(item) == 2 and paired.count(item) >= 2, item
    with_condition = [i for s in plan if len(s["items"]) == 2 and s["conditions"]
                      for i in s["items"]]  # fmt: skip
    for effect in REALISTIC_EFFECTS:
        assert alone.count(effect) == 1 and with_condition.count(effect) == 1, effect
    # real parts' shapes: each alone, each drift paired with g-sensitivity and lever arm
    pairs = [set(s["items"]) for s in plan if len(s["items"]) == 2]
    for variant, (effect, _) in SHAPES.items():
        assert alone.count(variant) == 2, variant
        if effect == "temperature_drift":
            assert {variant, "g_sensitivity"} in pairs and {variant, "lever_arm"} in pairs
    assert {"temperature_axes", "g_sensitivity_matrix"} in pairs
    assert sum(not s["items"] for s in plan) == 2
    # two variants of one simulator effect never share a session
    for s in plan:
        names = [e["effect"] for e in s["effects"]]
        assert len(set(names)) == len(names), s["items"]


def test_plan_seals_the_diagnosable_effects_and_the_conditions_apart(plan):
    for s in plan:
        conditions = [i for i in s["items"] if i in CONDITIONS]
        assert s["conditions"] == conditions
        variant_of = {k: v[0] for k, v in {**HARSH, **SHAPES}.items()}
        expected = sorted(variant_of.get(i, i) for i in s["items"] if i not in CONDITIONS)
        assert s["diagnosable"] == expected
        assert "hand_tremor" not in s["diagnosable"]
        assert ("hand_tremor" in [e["effect"] for e in s["effects"]]) == ("hand_held" in conditions)
        assert s["preset"] == ("mems" if "mems_truth" in conditions else "random")
        assert s["exclude"] == []
        for item in s["items"]:  # drawn magnitudes inside the harsh ranges
            if item not in HARSH:
                continue
            effect, ranges = HARSH[item]
            params = next(e["params"] for e in s["effects"] if e["effect"] == effect)
            for k, v in ranges.items():
                if isinstance(v, list):
                    assert v[0] <= params[k] <= v[1], (item, k)
                else:
                    assert params[k] == v
    # the same item draws different magnitudes in different sessions
    gyr = {next(e["params"]["gyr_per_k"] for e in s["effects"] if e["effect"] == "temperature_drift")
           for s in plan if "temperature_harsh" in s["items"]}  # fmt: skip
    assert len(gyr) > 5


def test_a_stress_spec_renders_with_its_preset_protocol_and_effects(plan, tmp_path):
    spec = next(s for s in plan if set(s["items"]) == {"hand_held", "saturation_phases"})
    assert [e.name for e in spec_effects(spec)] == ["hand_tremor", "saturation"]
    folder, sealed = tmp_path / spec["name"], tmp_path / "sealed.json"
    render_blind_session(json.loads(json.dumps(spec)), folder, sealed)  # as Snakemake passes it
    assert not (folder / "truth.json").exists()
    key = json.loads(sealed.read_text())
    assert key["spec"]["diagnosable"] == ["saturation"]
    assert set(key["magnitudes"]) == {"hand_tremor", "saturation"}
    assert key["truth"]["protocol"]["cube_position_s"] == [2.5, 3.5]
    assert key["truth"]["effects"]["saturation"]["gyr"] == 1965
    positions = [s for s in key["truth"]["segments"] if s["kind"] == "position"]
    assert all(2.5 <= s["end_s"] - s["start_s"] <= 3.5 for s in positions)
    assert "hand_tremor" in key["truth"]["effects_realised"]


def test_a_session_that_cannot_be_read_is_recorded_as_a_crash(tmp_path):
    settings = DiagnosisSettings(replicas=5, seed=1, crn_seeds=2)
    result = diagnose_folder(tmp_path / "missing", "s99", imucal_version="0", settings=settings)
    assert result["failed"].startswith("FileNotFoundError")
    assert result["failed_in"] == "pipeline" and result["calibration"] is None
    assert result["explained"] == [] and "dataset.yaml" in "".join(result["traceback"])


def _diag(explained=(), noted=(), notes=(), calibration=None):
    return {
        "explained": list(explained), "noted": list(noted), "effects": [],
        "gap": {"significant": bool(explained)}, "remaining": {"significant": False},
        "pipeline_notes": list(notes), "calibration": calibration,
    }  # fmt: skip


def _truth(gyr_bias=(0.1, 0.0, 0.0)):
    eye = np.eye(3).tolist()
    return {s: {"bias": list(gyr_bias) if s == "gyr" else [0.0] * 3, "matrix": eye}
            for s in ("acc", "gyr", "mag")}  # fmt: skip


def _key(items, diagnosable, conditions=()):
    return {"spec": {"items": list(items), "diagnosable": list(diagnosable),
                     "conditions": list(conditions)}, "truth": _truth()}  # fmt: skip


def test_score_counts_fully_right_sessions_crashes_and_empty_nulls():
    crash = failed_diagnosis("s4", "ValueError: cube: found 11 static (0-1 s, 4-5 s)\nmore")
    crash.update(
        failed_in="pipeline", where="imucal/segments/segmentation.py:10 find", calibration=None
    )
    calibration = _truth(gyr_bias=(0.1, 0.002, 0.0))
    calibration["acc"]["matrix"] = (np.eye(3) * 1.01).tolist()
    diagnoses = {
        "s0": _diag(["temperature_drift"], noted=["large_misalignment"], calibration=calibration),
        "s1": _diag(["temperature_drift", "packet_loss"]),  # one too many
        "s2": _diag([], notes=["eq. 36 (gyro scale without tools) failed: repeated stamps"]),
        "s3": _diag(["bias_instability"]),  # a condition named as an effect
        "s4": crash,
        "s5": failed_diagnosis("s5", "ValueError: cube: found 2 static (3.5-4.1 s)"),
        "s6": _diag([]),
    }
    keys = {
        "s0": _key(["temperature_harsh", "large_misalignment"],
                   ["large_misalignment", "temperature_drift"]),
        "s1": _key(["temperature_harsh"], ["temperature_drift"]),
        "s2": _key(["slow_handling"], [], ["slow_handling"]),
        "s3": _key(["hand_held"], [], ["hand_held"]),
        "s4": _key(["mems_truth"], [], ["mems_truth"]),
        "s5": _key(["hand_held", "lever_arm"], ["lever_arm"], ["hand_held"]),
        "s6": _key([], []),
    }  # fmt: skip
    score = score_stress(diagnoses, keys)
    assert score["n"] == 7 and score["crashes"] == 2
    assert score["fully_right"] == [3, 7]  # s0, s2, s6
    assert score["fully_right_fraction"] == pytest.approx(3 / 7)
    assert score["null_explained_empty"] == [2, 4]  # s2, s6; s3 named an effect, s4 crashed
    rows = {r["name"]: r for r in score["sessions"]}
    assert rows["s1"]["extra"] == ["packet_loss"] and not rows["s1"]["fully_right"]
    assert rows["s5"]["missed"] == ["lever_arm"]
    assert rows["s2"]["stages_not_run"][0].startswith("eq. 36")
    assert rows["s4"]["error"] == "ValueError: cube: found 11 static (0-1 s, 4-5 s)"
    assert score["crash_groups"] == {"ValueError: cube: found # static (...)": ["s4", "s5"]}
    assert score["crash_where"]["imucal/segments/segmentation.py:10 find"] == ["s4"]
    assert score["by_item"]["hand_held"] == {"n": 2, "crashed": 1, "fully_right": 0}
    assert score["by_item"]["clean"] == {"n": 1, "crashed": 0, "fully_right": 1}
    err = rows["s0"]["calibration_error"]
    assert err["gyr"]["bias"] == pytest.approx(0.002) and err["acc"]["matrix"] == pytest.approx(
        0.01
    )
    assert "calibration_error" not in rows["s4"]
    assert score["calibration_error_median"]["acc"]["matrix"] == pytest.approx(0.01)
