"""The blind check's scorer (imucal.gap.blind.score_blind) on hand-made diagnoses and keys."""

from __future__ import annotations

import numpy as np
import pytest

from imucal.gap.blind import (
    SHAPES,
    blind_plan,
    failed_diagnosis,
    public_plan,
    score_blind,
    spec_effects,
)
from imucal.sim import make_effect


def _diag(explained=(), noted=(), significant=False, remaining=False, effects=()):
    return {
        "explained": list(explained), "noted": list(noted), "effects": list(effects),
        "gap": {"significant": significant}, "remaining": {"significant": remaining,
        "locations": [{"stage": "acc_table", "sensor": "acc", "axis": "x",
                       "statistic": "omega2"}] if remaining else []},
    }  # fmt: skip


def _key(effect, exclude=(), magnitude=None):
    return {"spec": {"effect": effect, "exclude": list(exclude)},
            "magnitude": None if magnitude is None else {"value": magnitude}}  # fmt: skip


def test_scores_hits_noted_nulls_and_unknowns():
    lever = {"name": "lever_arm", "params": {"x_m": 0.05, "y_m": 0.0, "z_m": 0.0},
             "heldout_shrink": 0.9}  # fmt: skip
    diagnoses = {
        "b0": _diag(["lever_arm"], significant=True, effects=[lever]),
        "b1": _diag(["packet_loss"], significant=True),  # a miss: wrong effect named
        "b2": _diag([], noted=["large_misalignment"]),  # noted, nothing explained: a hit
        "b3": _diag([], noted=["large_misalignment"]),  # no effect: explained empty
        "b4": _diag(["time_offset"], significant=True),  # no effect: a false positive
        "b5": _diag([], significant=True, remaining=True),  # unknown effect, flagged
        "b6": failed_diagnosis("b6", "the pipeline refused it"),  # a miss
    }
    keys = {
        "b0": _key("lever_arm", magnitude=0.04), "b1": _key("g_sensitivity"),
        "b2": _key("large_misalignment"), "b3": _key(None), "b4": _key(None),
        "b5": _key("lever_arm", exclude=["lever_arm"]), "b6": _key("saturation"),
    }  # fmt: skip
    score = score_blind(diagnoses, keys)
    assert score["n_effect_sessions"] == 4
    # fully right: b0 (named alone), b2 (noted, opens no gap), b3 (nothing), b5 (flagged)
    assert score["fully_right"] == [4, 7] and score["n"] == 7 and score["crashes"] == 1
    assert score["top1"] == pytest.approx(2 / 4)
    assert score["top1_explained_only"] == pytest.approx(1 / 4)
    assert score["null_explained_empty"] == [1, 2]
    assert score["confusion"]["large_misalignment"] == {"large_misalignment (noted)": 1}
    assert score["confusion"]["g_sensitivity"] == {"packet_loss": 1}
    assert score["confusion"]["saturation"] == {"none": 1}
    assert score["magnitude_rel_error"]["lever_arm"] == pytest.approx(0.25)
    # held-out shrink of the true effect: 0.9 where evaluated, 0 elsewhere
    assert score["median_heldout_shrink_true"] == pytest.approx(0.0)
    (unknown,) = score["unknown"]
    assert unknown["flagged"] and unknown["remaining_locations"] == ["acc_table/acc/x/omega2"]


def test_an_unknown_effect_named_as_another_is_not_flagged():
    score = score_blind(
        {"u": _diag(["bias_instability"], significant=True, remaining=True)},
        {"u": _key("g_sensitivity", exclude=["g_sensitivity"])},
    )
    assert score["unknown"][0]["flagged"] is False


def test_plan_hides_the_effects_behind_names():
    plan = blind_plan(6, 2, 5, {"lever_arm": 1}, effects=["lever_arm", "time_offset"])
    assert [s["name"] for s in plan] == [f"b{i:02d}" for i in range(10)]
    assert sorted(str(s["effect"]) for s in plan).count("None") == 5
    public = public_plan(plan)
    assert set(public) == {s["name"] for s in plan}
    assert sum(bool(v) for v in public.values()) == 1
    assert all("effect" not in str(v) for v in public.values())


def test_score_check_refuses_an_unknown_check():
    from imucal.gap.checks import score_check

    with pytest.raises(ValueError, match="expected one of"):
        score_check("blindfold", [], [], [])


def test_plan_draws_the_shapes_of_real_parts():
    """Each shape's sessions carry their own draw: a temperature drift per axis with mixed
    signs at the variant's size (RMS over the axes that of the realistic default times 0.5, 1
    or 2), a g-sensitivity with every element of G set; the draws are reproducible."""
    plan = blind_plan(6, 1, 0, {}, effects=["lever_arm"], shapes=2)
    assert plan == blind_plan(6, 1, 0, {}, effects=["lever_arm"], shapes=2)
    shaped = [s for s in plan if "shape" in s]
    assert sorted(s["shape"] for s in shaped) == sorted(list(SHAPES) * 2)
    real = make_effect("temperature_drift")
    rms = lambda v: float(np.sqrt(np.mean(np.square(v))))  # noqa: E731
    for spec in shaped:
        (effect,) = spec_effects(spec)
        assert effect.name == spec["effect"] == SHAPES[spec["shape"]][0]
        factor = SHAPES[spec["shape"]][1]
        if effect.name == "temperature_drift":
            for key in ("acc_per_k", "gyr_per_k", "acc_scale_per_k", "gyr_scale_per_k"):
                v = np.array(getattr(effect, key))
                assert np.any(v < 0) and np.any(v > 0), (key, v)
                assert rms(v) == pytest.approx(factor * rms(getattr(real, key)), rel=1e-9)
        else:
            g = np.array(effect.matrix)
            assert np.all(g != 0) and np.all(np.abs(np.diag(g)) >= 1.8e-4), g
    first = [s for s in shaped if s["shape"] == "temperature_axes"]
    assert first[0]["effects"] != first[1]["effects"]


def test_the_blind_page_shows_the_detection_limits_where_a_sweep_was_run(tmp_path):
    """score_check('blind', ..., detection_score=...): the sweep's limits and its clean
    sessions' false positives on the blind page; without the file, the page says so."""
    from imucal.gap.checks import score_check
    from imucal.gap.detection import score_detection
    from imucal.io import write_json

    folder = tmp_path / "blind"
    folder.mkdir()
    paths = {}
    for kind, content in (("diag", _diag(["lever_arm"], significant=True)),
                          ("key", _key("lever_arm"))):  # fmt: skip
        paths[kind] = folder / f"{kind}" / "b0.json"
        paths[kind].parent.mkdir()
        write_json(content, paths[kind])
    sweep = {}
    for j in range(5):
        sweep[f"d{j}"] = ({"explained": ["lever_arm"], "noted": [], "effects": [],
                           "gap": {"significant": True}, "remaining": {"significant": False}},
                          {"spec": {"effect": "lever_arm", "factor": 0.25,
                                    "magnitude_si": {"value": 0.009, "unit": "m"}},
                           "magnitude": {"value": 0.009, "unit": "m"}})  # fmt: skip
    detection = score_detection(
        {k: d for k, (d, _) in sweep.items()}, {k: s for k, (_, s) in sweep.items()},
        rate=0.9, confidence=0.95,
    )  # fmt: skip
    write_json(detection, tmp_path / "score.json")
    bench = tmp_path / "b0.tsv"  # a Snakemake benchmark file of the diagnose rule
    bench.write_text("s\th:m:s\tmax_rss\n12.5\t0:00:12\t300.0\n")
    args = ("blind", [paths["diag"]], [paths["key"]], [bench])
    _, page = score_check(*args, detection_score=tmp_path / "score.json")
    assert "Detection limits (detection sweep: 5 effect sessions)" in page
    assert "<th>lever_arm</th><td>x0.25</td><td>0.009 m</td>" in page
    _, page = score_check(*args, detection_score=tmp_path / "absent.json")
    assert "No detection sweep in this folder" in page
