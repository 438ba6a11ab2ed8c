"""The gap verdict as the report writes it (imucal.report.gapsection): sizes in units, one order
of the effects, what is left and whether it is within noise, the clock offset reconciled."""

import copy

import pytest

from imucal.report.gapfigures import ordered_effects, plot_effects, plot_gap_map
from imucal.report.gapsection import (
    reconcile_offset,
    verdict_paragraph,
    verdict_sentence,
)

LOCATION = {"stage": "validate", "sensor": "clock", "axis": "-", "segment": "rotation3d",
            "statistic": "ref_offset_s", "z": 1181.1, "in_gap": True}  # fmt: skip
LOSS = {"stage": "ingest", "sensor": "clock", "axis": "-", "segment": "all",
        "statistic": "loss_fraction", "z": 217.9, "in_gap": True}  # fmt: skip


def _effect(name, params, accepted, heldout=None, **extra):
    return {"name": name, "params": params, "accepted": accepted, "evaluated": accepted,
            "heldout_shrink": heldout, "shrink": heldout, "gap_before": 10.0, "gap_after": 1.0,
            "detect_z": 50.0, "judged_beside_shortfalls": False, "note": "", **extra}  # fmt: skip


#: The demo's diagnosis in its form: the effects ranked by held-out shrink (packet loss first),
#: ``explained`` in the order they were added (time offset first).
DEMO = {
    "dataset": "demo",
    "gap": {"total": 1442497.35, "null_p95": 33.48, "significant": True},
    "locations": [LOCATION, LOSS],
    "all_locations": [
        LOCATION,
        LOSS,
        {**LOSS, "statistic": "stamp_scatter_s", "z": 0.2, "in_gap": False},
    ],  # fmt: skip
    "effects": [
        _effect(
            "packet_loss",
            {"fraction": 0.004466, "model": "gilbert", "burst_mean": 3.595},
            True,
            0.99963,
        ),  # fmt: skip
        _effect("time_offset", {"offset_s": 0.31996, "drift_ppm": 10.26}, True, 0.98624),
        _effect(
            "lever_arm",
            {"x_m": 1e-5, "y_m": 2e-6, "z_m": 0.0},
            False,
            note="estimate within the null",
        ),  # fmt: skip
    ],
    "explained": ["time_offset", "packet_loss"],
    "remaining": {"total": 0.0, "significant": False, "locations": []},
    "null": {"replicas": 20, "alpha": 0.05, "n_locations": 70},
    "verdict": {
        "outcome": "effect",
        "lacks": [],
        "effects": [
            {"name": "time_offset", "kind": "acquisition"},
            {"name": "packet_loss", "kind": "acquisition"},
        ],
    },  # fmt: skip
}


def test_the_verdict_names_the_effects_with_their_sizes_in_the_order_they_were_added():
    text = verdict_paragraph(DEMO)
    assert "departs from its simulated twin at 2 of its 70 statistics" in text
    assert "most of all in the reference clock offset (clock, rotation3d)" in text
    first = text.index("first an offset of the reference's clock (the reference started 0.32 s")
    then = text.index("then packet loss (0.45 % of the packets lost in bursts of 3.6 packets")
    assert first < then
    assert "closes 98.6 % of the gap on data its estimate did not use" in text
    assert "closes 100 % of what was left, also held out" in text
    assert "of the acquisition (clocks, radio link, logger) rather than of the sensor" in text
    assert "What is left, a gap of 0, is within noise (below 33.5)." in text
    # statistic names stay in the details
    assert "ref_offset_s" not in text and "loss_fraction" not in text and "_" not in text
    sentence = verdict_sentence(DEMO)
    assert sentence.startswith("explained by an offset of the reference's clock (the reference ")
    assert sentence.index("offset") < sentence.index("packet loss")
    assert sentence.endswith("what is left is within noise.")


def test_the_order_is_the_order_of_explained_everywhere():
    names = [e["name"] for e in ordered_effects(DEMO)]
    assert names == ["time_offset", "packet_loss", "lever_arm"]
    labels = [t.get_text() for t in plot_effects(DEMO).axes[0].get_yticklabels()]
    assert labels[0].startswith("an offset of the reference's clock")
    assert labels[1].startswith("packet loss")


def test_a_gap_left_beyond_noise_says_what_the_twin_lacks():
    d = copy.deepcopy(DEMO)
    left = {"stage": "ingest", "sensor": "clock", "axis": "imu", "segment": "static",
            "statistic": "burst_fraction", "z": 40.2, "in_gap": True}  # fmt: skip
    d["remaining"] = {"total": 2782.0, "significant": True, "locations": [left]}
    d["verdict"]["lacks"] = [{"what": "the host's receive timing", "share": 1.0}]
    text = verdict_paragraph(d)
    assert (
        "What is left, a gap of 2782, is not within noise: the twin lacks the host's receive "
        "timing, above all in the share of packets back to back (clock imu, static)." in text
    )
    assert verdict_sentence(d).endswith("what is left is not within noise.")
    # nothing accepted: no effect closes it
    d["effects"] = [dict(e, accepted=False) for e in d["effects"]]
    d["explained"] = []
    text = verdict_paragraph(d)
    assert "No effect of the library closes the gap on data withheld from its fit: the twin " \
        "lacks the host's receive timing" in text  # fmt: skip
    assert "no effect explains it: the twin lacks the host's receive timing" in verdict_sentence(d)


def test_a_session_like_its_twin_and_one_not_compared():
    d = copy.deepcopy(DEMO)
    d["gap"] = {"total": 0.0, "null_p95": 9.23, "significant": False}
    d["effects"], d["explained"] = [], []
    assert verdict_paragraph(d).startswith(
        "The session behaves like its simulated twin: none of its 70 statistics departs"
    )
    assert verdict_sentence(d) == "nothing departs from the simulated twin beyond noise."
    none = {"scope": "none", "reason": "the session has no static recording"}
    assert verdict_sentence(none) == (
        "not compared with a simulated twin: the session has no static recording."
    )
    assert "could not be compared" in verdict_paragraph(none)


def test_the_reference_clock_offset_is_reconciled_with_the_validation():
    validation = {"time_alignment": {"offset_s": 18.37526, "drift_ppm": 10.26}}
    summary = {"recordings": {"reference": {"t_start_s": 18.0553},
                              "rotation3d": {"t_start_s": 0.0}}}  # fmt: skip
    offset = reconcile_offset(DEMO, validation, summary)
    assert offset == {"validation_s": "18.3753", "first_stamp_s": "18.0553", "lead_s": "0.32",
                      "diagnosis_s": "0.32", "accepted": True}  # fmt: skip
    # without a diagnosis the validation still says how much earlier the reference started
    assert reconcile_offset(None, validation, summary)["diagnosis_s"] is None
    assert reconcile_offset(DEMO, validation, {"recordings": {}}) is None


@pytest.mark.parametrize("diagnosis", [DEMO])
def test_the_gap_map_speaks_plain_words(diagnosis):
    ax = plot_gap_map(diagnosis).axes[0]
    columns = [t.get_text() for t in ax.get_xticklabels()]
    rows = [t.get_text() for t in ax.get_yticklabels()]
    assert "reference clock offset (s)" in columns and "share of packets lost" in columns
    assert "clock, reference clock, rotation3d" in rows
    assert not any("_" in t for t in columns + rows)
