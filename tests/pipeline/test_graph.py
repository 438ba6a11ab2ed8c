"""The stage graph: each stage chooses its samples in one place, whichever path runs it, and a
stage that can do without one of its inputs still runs when that input did not."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import partial_session

from imucal.columns import ACC, MAG
from imucal.io.dataset import read_dataset
from imucal.pipeline import partial
from imucal.pipeline.graph import FULL_PROTOCOL, SETTINGS, Node, run_graph, run_nodes, usable
from imucal.pipeline.options import PipelineOptions
from imucal.pipeline.outcome import NotApplicable, NotShipped, not_run_reason
from imucal.pipeline.stages import fit_acc_cube
from imucal.segments.filtering import lowpass_recording
from imucal.segments.segmentation import segment_dataset

REPO = Path(__file__).resolve().parents[2]
G = 9.81


@pytest.fixture(scope="module")
def demo(ingest_imu):
    dataset = read_dataset(REPO / "data" / "demo")
    imu = ingest_imu(dataset)
    options = PipelineOptions.of_dataset(dataset, with_covariance=False)
    segments = segment_dataset(imu, ratetable=dict(dataset.ratetable), fallback=True)
    return imu, segments, options


def test_every_node_takes_known_settings_and_reads_known_sources() -> None:
    for node in FULL_PROTOCOL.values():
        assert set(node.settings) <= set(SETTINGS), node.name
        sources = set(node.reads(frozenset({"rotation3d", "cube", "static", "ratetable"})).values())
        earlier = set(list(FULL_PROTOCOL)[: list(FULL_PROTOCOL).index(node.name)])
        known = {"rotation3d", "cube", "static", "ratetable", "lowpass", "segments", "truth"}
        assert sources <= known | earlier, (node.name, sources - known - earlier)


def _one_sided_poses(n_per_side: int = 4) -> tuple[pd.DataFrame, pd.DataFrame]:
    """A cube recording whose 12 poses show gravity along +x, +y and +z only."""
    rng = np.random.default_rng(5)
    rows, blocks, start = [], [], 0
    for k, up in enumerate(np.repeat(np.eye(3), n_per_side, axis=0)):
        values = G * up + 0.01 * rng.standard_normal((200, 3))
        blocks.append(values)
        rows.append(
            {"recording": "cube", "kind": "position", "label": f"p{k}",
             "start_index": start, "end_index": start + 200}
        )  # fmt: skip
        start += 200
    values = np.vstack(blocks)
    table = pd.DataFrame(values, columns=list(ACC))
    table["t_s"] = np.arange(len(table)) / 100.0
    return table, pd.DataFrame(rows)


def test_the_cube_fit_refuses_poses_that_do_not_determine_it_on_either_path() -> None:
    table, segments = _one_sided_poses()
    with pytest.raises(NotApplicable, match="distinct orientations"):
        fit_acc_cube({"cube": table}, segments, gravity_m_s2=G, saturation_limit_m_s2=None)
    outcomes = {
        o.name: o for o in partial.run_stages(partial_session({"cube": table}, segments, G))
    }
    assert outcomes["acc_cube"].status == "skipped"
    assert "distinct orientations" in outcomes["acc_cube"].reason


def test_the_tool_free_scale_is_tried_on_the_accelerometer_when_the_magnetometer_did_not_run(
    demo,
) -> None:
    # eq. 36 needs one calibrated sensor of two to measure the phase angles: without the
    # magnetometer it runs on the accelerometer, which cannot see the turn about gravity (z),
    # and says so; the rate table still calibrates the gyroscope
    imu, segments, options = demo
    no_mag = {name: table.assign(**dict.fromkeys(MAG, np.nan)) for name, table in imu.items()}
    low = lowpass_recording(
        no_mag["rotation3d"], order=options.lowpass_order, cutoff_hz=options.lowpass_cutoff_hz
    )
    store = run_nodes({**no_mag, "lowpass": low, "segments": segments}, options)
    assert "no recording has magnetometer samples" in not_run_reason(store["mag_step1"])
    assert not_run_reason(store["mag_step2"]).startswith("mag_step2 did not run: mag_step1")
    reason = not_run_reason(store["gyr_scale"])
    assert "phase 'z'" in reason and "use the magnetometer" in reason
    assert "mag_step2" not in reason
    assert usable(store["gyr"]) is not None and usable(store["acc_align"]) is not None


def test_the_runner_records_what_did_not_run_and_keeps_only_reviewed_results() -> None:
    # a stage whose conditions fail, one that needs it, one that tolerates it, and one whose
    # result the review refuses: each gets its record, and later stages see the records
    def node(name: str, reads: dict, run, tolerates: tuple = ()) -> Node:
        return Node(name, f"{name}.json", lambda recordings: reads, run, tolerates=tolerates)

    def cannot(i, s, d):
        raise NotApplicable("needs what this session lacks")

    seen = {}

    def keep(name: str):
        def run(i, s, d):
            seen[name] = dict(i)
            return {"value": name}, {}

        return run

    nodes = {
        n.name: n
        for n in (
            node("first", {"x": "x"}, cannot),
            node("strict", {"first": "first"}, keep("strict")),
            node("lenient", {"first": "first"}, keep("lenient"), tolerates=("first",)),
            node("refused", {"x": "x"}, keep("refused")),
            node("after", {"refused": "refused"}, keep("after"), tolerates=("refused",)),
        )
    }

    def review(name: str, artifact: dict, store) -> dict:
        if name == "refused":
            raise NotShipped("fitted but not shipped: outside its bounds")
        return {**artifact, "reviewed": True}

    store = run_graph({"x": 1.0}, lambda n: {}, nodes, review=review)
    assert not_run_reason(store["first"]) == "first did not run: needs what this session lacks"
    assert not_run_reason(store["strict"]).startswith("strict did not run: first did not run")
    assert "strict" not in seen
    assert store["lenient"] == {"value": "lenient", "reviewed": True}
    assert not_run_reason(seen["lenient"]["first"]) is not None  # the record, not a result
    assert not_run_reason(store["refused"]) == (
        "refused did not run: fitted but not shipped: outside its bounds"
    )
    assert usable(seen["after"]["refused"]) is None
