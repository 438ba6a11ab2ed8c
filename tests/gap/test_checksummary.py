"""The checks' summary: spread effects named where they were not injected, over all sets."""

import json

import pytest

from imucal.gap.checksummary import (
    check_sentences,
    injected_effects,
    spread_effects,
    spread_false_names,
    summarize_checks,
)
from imucal.report.docblocks import replace_block


def test_the_spread_effects_are_the_library_kind_spread():
    assert {"bias_instability", "timing_jitter", "reference_jitter"} <= set(spread_effects())
    assert "lever_arm" not in spread_effects()


def test_every_spec_form_gives_its_injected_effects():
    assert injected_effects({"effect": "lever_arm", "exclude": []}) == {"lever_arm"}
    assert injected_effects({"effect": None}) == set()
    assert injected_effects(
        {"effects": [{"effect": "bias_step", "params": {}}], "diagnosable": ["time_offset"]}
    ) == {"bias_step", "time_offset"}


def _diag(*explained):
    return {"explained": list(explained)}


def test_a_spread_effect_counts_only_where_it_was_not_injected():
    diagnoses = {
        "blind": {"b1": _diag("bias_instability"), "b2": _diag("bias_instability"),
                  "b3": _diag("lever_arm")},
        "outside": {"o1": _diag("timing_jitter", "time_offset"), "o2": _diag()},
    }  # fmt: skip
    keys = {
        "blind": {"b1": {"spec": {"effect": "bias_instability"}},
                  "b2": {"spec": {"effect": "lever_arm"}},
                  "b3": {"spec": {"effect": "lever_arm"}}},
        "outside": {"o1": {"spec": {"effects": [{"effect": "bias_step", "params": {}}],
                                    "diagnosable": ["time_offset"]}},
                    "o2": {"spec": {"effect": None}}},
    }  # fmt: skip
    out = spread_false_names(diagnoses, keys)
    assert out["by_check"] == {"blind": [1, 3], "outside": [1, 2]}
    assert out["total"] == [2, 5]
    assert out["sessions"] == {"blind/b2": ["bias_instability"], "outside/o1": ["timing_jitter"]}
    text = check_sentences({}, out)
    assert "2 of 5 sessions" in text and "blind/b2" in text


def test_the_summary_reads_the_files_and_says_each_figure(tmp_path):
    for name, effect, explained in (("b1", "lever_arm", ["lever_arm"]), ("b2", None, [])):
        (tmp_path / f"{name}.diag.json").write_text(json.dumps(_diag(*explained)))
        (tmp_path / f"{name}.key.json").write_text(json.dumps({"spec": {"effect": effect}}))
    score = {"n": 2, "crashes": 0, "fully_right": [2, 2], "null_explained_empty": [1, 1],
             "sessions": []}  # fmt: skip
    (tmp_path / "score.json").write_text(json.dumps(score))
    for kind in ("diag", "key"):
        for name in ("b1", "b2"):
            (tmp_path / kind).mkdir(exist_ok=True)
            (tmp_path / f"{name}.{kind}.json").rename(tmp_path / kind / f"{name}.json")
    files = {"blind": {"diagnoses": sorted((tmp_path / "diag").glob("*.json")),
                       "sealed": sorted((tmp_path / "key").glob("*.json")),
                       "score": tmp_path / "score.json"}}  # fmt: skip
    summary, text = summarize_checks(files)
    assert summary["scores"]["blind"]["fully_right"] == [2, 2]
    assert "sessions" not in summary["scores"]["blind"]
    assert "Blind set (2 sessions): 2 of 2 fully right, 0 crashes" in text
    assert "0 of 2 sessions" in text
    assert summary["largest_z"] == {"by_check": {"blind": None}, "beyond": []}


def test_a_score_from_a_null_without_spread_is_found_in_any_set():
    from imucal.gap.checksummary import largest_z

    loc = lambda z: {"stage": "s", "z": z}  # noqa: E731
    out = largest_z({"stress": {"s1": {"all_locations": [loc(-1.7e15), loc(2.0)]},
                                "s2": {"all_locations": [loc(None), loc(float("nan"))]}},
                     "blind": {"b1": {"all_locations": [loc(52.0)]}}})  # fmt: skip
    assert out == {"by_check": {"blind": 52.0, "stress": 1.7e15}, "beyond": ["stress/s1"]}


def test_a_generated_block_is_replaced_between_its_markers_only(tmp_path):
    doc = tmp_path / "doc.md"
    doc.write_text("a\n<!-- generated: x -->\nold\n<!-- end: x -->\nb\n")
    replace_block(doc, "x", "new\n")
    assert doc.read_text() == "a\n<!-- generated: x -->\nnew\n<!-- end: x -->\nb\n"
    with pytest.raises(ValueError, match="no block"):
        replace_block(doc, "y", "new")
