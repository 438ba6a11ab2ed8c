"""The detection sweep (imucal.gap.detection): its plan and its scorer on hand-made diagnoses."""

from __future__ import annotations

import json
from collections import Counter

import pytest

from imucal.gap.blind import failed_diagnosis, render_blind_session
from imucal.gap.detection import (
    clopper_pearson_lower,
    detection_levels,
    detection_plan,
    library_effects,
    named_needed,
    score_detection,
)
from imucal.gap.library import scope_library
from imucal.sim import SENSITIVITY
from imucal.sim.effects import make_effect

FACTORS = [0.125, 0.25, 0.5, 1, 2, 4]
#: The effects the full protocol's diagnosis estimates.
LIBRARY = scope_library("protocol")


@pytest.fixture(scope="module")
def plan():
    return detection_plan(8, FACTORS, 3)


def test_plan_is_deterministic_and_covers_every_effect_factor_and_seed(plan):
    assert plan == detection_plan(8, FACTORS, 3)
    assert [s["seed"] for s in plan] != [s["seed"] for s in detection_plan(9, FACTORS, 3)]
    assert set(library_effects()) == set(LIBRARY)
    cells = Counter((s["effect"], s["factor"]) for s in plan)
    # saturation's gyro range times 4 is beyond int16: no such session
    expected = {(e, f): 3 for e in LIBRARY for f in FACTORS if (e, f) != ("saturation", 4)}
    assert cells == expected
    assert len(plan) == 3 * (len(LIBRARY) * len(FACTORS) - 1)
    # the same seeds (truths) at every factor of an effect, different ones between effects
    seeds = {(s["effect"], s["factor"]): set() for s in plan}
    for s in plan:
        seeds[(s["effect"], s["factor"])].add(s["seed"])
    for e in LIBRARY:
        assert len({frozenset(seeds[(e, f)]) for f in FACTORS if (e, f) in seeds}) == 1, e
    assert seeds[("lever_arm", 1)].isdisjoint(seeds[("packet_loss", 1)])


def test_names_hide_the_effect(plan):
    names = [s["name"] for s in plan]
    assert names == [f"d{i:03d}" for i in range(len(plan))]
    for s in plan:
        assert not any(e in s["name"] for e in LIBRARY)
    # shuffled: the first sessions are not one effect's
    assert len({s["effect"] for s in plan[:20]}) > 5


def test_the_key_holds_the_scaled_magnitude(plan):
    for s in plan:
        effect = make_effect(s["effect"]).scaled(s["factor"])
        assert s["magnitude"]["value"] == pytest.approx(effect.magnitude().value)
        assert s["effects"] == [{"effect": s["effect"], "params": effect.params()}]
    lever = next(s for s in plan if s["effect"] == "lever_arm" and s["factor"] == 0.25)
    realistic = make_effect("lever_arm").magnitude().value
    assert lever["magnitude"]["value"] == pytest.approx(0.25 * realistic)
    assert lever["magnitude_si"] == {"value": lever["magnitude"]["value"], "unit": "m"}


def test_mag_latency_scales_its_mean_age_and_saturation_its_clip_level():
    levels = detection_levels(FACTORS, ["mag_latency", "saturation"])
    age = make_effect("mag_latency").magnitude().value
    for f in FACTORS:
        assert levels["mag_latency"][f].magnitude().value == pytest.approx(f * age)
    assert levels["saturation"][2].gyr == 32750
    assert levels["saturation"][0.125].gyr == 2047
    assert "outside 1..32767" in levels["saturation"][4]
    with pytest.raises(ValueError, match="not in the diagnosis's library"):
        detection_levels(FACTORS, ["hand_tremor"])
    with pytest.raises(ValueError, match="distinct and > 0"):
        detection_levels([1, 1])


def test_a_detection_spec_renders_with_its_magnitude_sealed(plan, tmp_path):
    spec = next(s for s in plan if s["effect"] == "lever_arm" and s["factor"] == 2)
    folder, sealed = tmp_path / spec["name"], tmp_path / "sealed.json"
    render_blind_session(json.loads(json.dumps(spec)), folder, sealed)  # as Snakemake passes it
    assert not (folder / "truth.json").exists()
    key = json.loads(sealed.read_text())
    assert key["spec"]["effect"] == "lever_arm" and key["spec"]["factor"] == 2
    assert key["magnitude"]["value"] == pytest.approx(spec["magnitude"]["value"])
    assert "lever_arm" not in (folder / "dataset.yaml").read_text()


def test_the_criterion_and_the_clopper_pearson_bound():
    assert [named_needed(n, 0.9) for n in (5, 7, 10, 20, 29)] == [5, 7, 9, 18, 27]
    assert clopper_pearson_lower(9, 10, 0.95) == pytest.approx(0.6058, abs=1e-4)
    assert clopper_pearson_lower(10, 10, 0.95) == pytest.approx(0.05**0.1)
    assert clopper_pearson_lower(0, 10, 0.95) == 0.0
    with pytest.raises(ValueError, match="0 <= k <= n"):
        clopper_pearson_lower(11, 10, 0.95)


def _diag(explained=(), noted=(), effects=()):
    return {"explained": list(explained), "noted": list(noted), "effects": list(effects),
            "gap": {"significant": bool(explained)}, "remaining": {"significant": False}}  # fmt: skip


def _key(effect, factor, value, unit="m"):
    return {
        "spec": {"effect": effect, "factor": factor,
                 "magnitude_si": {"value": value, "unit": unit}},
        "magnitude": {"value": value, "unit": unit},
    }  # fmt: skip


def _sessions(effect, named_by_factor, n=10, unit="m", other=None):
    """Sessions of one effect: at factor f, the first k of n name it (k from the dict)."""
    diagnoses, keys = {}, {}
    for f, k in named_by_factor.items():
        for j in range(n):
            name = f"{effect}_{f}_{j}"
            if effect == "large_misalignment":
                diagnoses[name] = _diag(noted=[effect] if j < k else [])
            else:
                diagnoses[name] = _diag([effect] if j < k else ([other] if other else []))
            keys[name] = _key(effect, f, 0.01 * f, unit)
    return diagnoses, keys


def _score(*parts):
    diagnoses = {k: v for d, _ in parts for k, v in d.items()}
    keys = {k: v for _, ks in parts for k, v in ks.items()}
    return score_detection(diagnoses, keys, rate=0.9, confidence=0.95)


def test_a_monotone_effect_is_detected_from_its_smallest_factor_at_the_rate():
    score = _score(_sessions("lever_arm", {0.25: 3, 0.5: 9, 1: 10, 2: 10}))
    e = score["effects"]["lever_arm"]
    assert [lv["named"] for lv in e["levels"]] == [3, 9, 10, 10]
    assert [lv["detected"] for lv in e["levels"]] == [False, True, True, True]
    assert e["limit"]["factor"] == 0.5
    assert e["limit"]["magnitude_si"] == pytest.approx(0.005) and e["limit"]["unit_si"] == "m"
    assert e["limit"]["cp_lower"] == pytest.approx(0.6058, abs=1e-4)
    assert e["levels"][0]["rate"] == pytest.approx(0.3) and e["levels"][0]["needed"] == 9


def test_a_non_monotone_effect_is_detected_only_above_its_last_miss():
    # named at 0.25 by chance, missed at 0.5: the limit is 1, not 0.25
    score = _score(_sessions("packet_loss", {0.25: 9, 0.5: 8, 1: 10, 2: 9}, unit="1"))
    assert score["effects"]["packet_loss"]["limit"]["factor"] == 1
    # missed at the harshest level: no limit, and the note says why
    score = _score(_sessions("packet_loss", {0.5: 10, 1: 10, 2: 6}, unit="1"))
    e = score["effects"]["packet_loss"]
    assert e["limit"] is None and "harshest level is missed" in e["limit_note"]


def test_an_effect_never_reached_and_false_positives():
    score = _score(
        _sessions("earth_rotation", {0.5: 0, 1: 2, 4: 8}, unit="rad/s", other="g_sensitivity")
    )
    e = score["effects"]["earth_rotation"]
    assert e["limit"] is None and e["limit_note"] == "not reached in the grid"
    assert [lv["other_explained"] for lv in e["levels"]] == [10, 8, 2]
    assert score["false_positive"] == [20, 30]


def test_large_misalignment_is_named_by_noted_and_saturation_counts_down():
    score = _score(
        _sessions("large_misalignment", {0.5: 7, 1: 10, 2: 10}, unit="rad"),
        # saturation gets harsher as the factor (the clip level) falls
        _sessions("saturation", {0.25: 10, 0.5: 10, 1: 9, 2: 0}, unit="counts"),
    )
    assert score["effects"]["large_misalignment"]["limit"]["factor"] == 1
    assert score["effects"]["saturation"]["limit"]["factor"] == 1
    assert list(score["effects"]) == ["saturation", "large_misalignment"]  # simulator's order
    assert score["false_positive"] == [0, 70]


def test_a_crash_names_nothing_and_the_estimates_of_the_named_are_summarised():
    lever = [{"name": "lever_arm", "params": {"x_m": 0.012, "y_m": 0.0, "z_m": 0.0},
              "heldout_shrink": 0.8}]  # fmt: skip
    diagnoses = {
        "d0": _diag(["lever_arm"], effects=lever),
        "d1": _diag(["lever_arm"], effects=lever),
        "d2": failed_diagnosis("d2", "ValueError: no static interval"),
        "d3": _diag(noted=["lever_arm", "large_misalignment"]),  # noted, not explained
    }
    keys = {n: _key("lever_arm", 1, 0.01) for n in diagnoses}
    score = score_detection(diagnoses, keys, rate=0.9, confidence=0.95)
    (lv,) = score["effects"]["lever_arm"]["levels"]
    assert (lv["named"], lv["n"], lv["crashed"], lv["detected"]) == (2, 4, 1, False)
    assert lv["noted_only"] == 1 and lv["other_noted"] == 1
    assert score["false_noted"] == [1, 4] and score["false_positive"] == [0, 4]
    assert lv["median_heldout_shrink"] == pytest.approx(0.8)
    assert lv["median_magnitude_rel_error"] == pytest.approx(0.2)
    assert score["crashes"] == 1


def test_saturation_magnitude_in_si_is_the_gyro_clip_rate(plan):
    s = next(s for s in plan if s["effect"] == "saturation" and s["factor"] == 1)
    assert s["magnitude"]["unit"] == "counts"
    assert s["magnitude_si"]["unit"] == "rad/s"
    assert s["magnitude_si"]["value"] == pytest.approx(16375 * SENSITIVITY["gyr"])


def test_clean_sessions_are_shuffled_in_and_their_false_positives_counted():
    plan = detection_plan(8, FACTORS, 1, ["lever_arm"], n_clean=4)
    clean = [s for s in plan if s["effect"] is None]
    assert len(clean) == 4 and all(s["effects"] == [] and s["magnitude"] is None for s in clean)
    assert len({s["seed"] for s in clean}) == 4
    assert [s["effect"] for s in plan][-4:] != [None] * 4  # not appended in a block
    diagnoses = {
        "c0": _diag(),
        "c1": _diag(["lever_arm"]),
        "c2": _diag(noted=["large_misalignment"]),
        "c3": failed_diagnosis("c3", "ValueError: no static interval"),
        "d0": _diag(["lever_arm"]),
    }
    keys = {n: {"spec": {"effect": None, "factor": None}, "magnitude": None} for n in diagnoses}
    keys["d0"] = _key("lever_arm", 1, 0.01)
    score = score_detection(diagnoses, keys, rate=0.9, confidence=0.95)
    assert score["clean_explained"] == [1, 4] and score["clean_noted"] == [1, 4]
    assert score["crashes"] == 1 and score["n"] == 1
    assert score["effects"]["lever_arm"]["levels"][0]["named"] == 1
