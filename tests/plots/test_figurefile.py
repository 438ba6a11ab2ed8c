"""Figures carry the record of their drawn texts, and the legibility check reads it: texts below
10 px where the report shows the figure, and texts that overlap, are found."""

import numpy as np
import pandas as pd
import pytest
from matplotlib.figure import Figure

from imucal.plots.figurefile import drawn_texts, legibility_problems, read_text_record, save_figure
from imucal.plots.segmentation import plot_segments
from imucal.plots.style import FIGURE_DPI, MIN_FONT_PT, MIN_TEXT_PX, PAGE_WIDTH_IN, PAGE_WIDTH_PX


def _saved(fig, tmp_path):
    path = save_figure(fig, tmp_path / "figure.png")
    return read_text_record(path.read_bytes())


def test_the_page_width_and_the_smallest_font_meet_the_smallest_text():
    assert PAGE_WIDTH_IN * FIGURE_DPI <= PAGE_WIDTH_PX
    assert MIN_FONT_PT / 72 * FIGURE_DPI >= MIN_TEXT_PX


def test_a_small_legend_and_a_wide_figure_are_found(tmp_path):
    fig = Figure(figsize=(PAGE_WIDTH_IN, 3), layout="constrained")
    ax = fig.add_subplot()
    ax.plot([0, 1], [0, 1], label="x axis")
    ax.legend(fontsize=6)  # 6 pt at 110 dpi: 9.2 px
    record = _saved(fig, tmp_path)
    assert record["dpi"] == FIGURE_DPI and record["width"] == int(PAGE_WIDTH_IN * FIGURE_DPI)
    assert legibility_problems(record, record["width"]) == [
        "'x axis': 6 pt renders at 9.2 px (< 10)"
    ]
    ax.legend(fontsize=MIN_FONT_PT)
    assert legibility_problems(_saved(fig, tmp_path), record["width"]) == []
    # 8 pt is legible unscaled but not in a figure 15.6 in wide shown 1086 px wide (the
    # Allan figure of three 5.2 in panels): 8 pt * 110 / 72 * 1086 / 1716 = 7.7 px
    wide = Figure(figsize=(15.6, 3))
    wide.text(0.5, 0.5, "legend", fontsize=8)
    wide_record = _saved(wide, tmp_path)
    problems = legibility_problems(wide_record, PAGE_WIDTH_PX)
    assert problems == ["'legend': 8 pt renders at 7.7 px (< 10)"]


def test_overlapping_texts_are_found_and_rotated_labels_side_by_side_are_not(tmp_path):
    fig = Figure(figsize=(6, 3))
    ax = fig.add_subplot()
    ax.set_xticks(range(6), [f"a long label {k}" for k in range(6)], rotation=60, ha="right",
                  rotation_mode="anchor")  # fmt: skip
    ax.text(2.0, 0.5, "first", fontsize=10)
    ax.text(2.05, 0.5, "second", fontsize=10)
    ax.set_xlim(-0.5, 5.5)
    problems = legibility_problems(_saved(fig, tmp_path), 6 * FIGURE_DPI)
    assert problems == ["'first' overlaps 'second'"]


def test_only_drawn_texts_are_recorded():
    fig = Figure(figsize=(4, 3))
    ax = fig.add_subplot()
    ax.set_xticks([0, 1, 2, 10], ["0", "1", "2", "outside"])
    ax.set_xlim(-0.5, 2.5)  # the tick at 10 is not drawn
    texts = [t.text for t in drawn_texts(fig)]
    assert "outside" not in texts and {"0", "1", "2"} <= set(texts)


def test_a_figure_saved_otherwise_has_no_record(tmp_path):
    fig = Figure(figsize=(2, 2))
    fig.savefig(tmp_path / "plain.png")
    with pytest.raises(ValueError, match="has no 'imucal:texts' record"):
        read_text_record((tmp_path / "plain.png").read_bytes())


def test_crowded_segment_labels_do_not_overlap(tmp_path):
    """Forty short segments of one recording, a label each: they go up in lanes, or upright
    when lanes do not suffice, and no two overlap."""
    t = np.arange(0, 200, 0.01)
    table = pd.DataFrame({"t_s": t, **{f"gyr_{a}": np.sin(t) for a in "xyz"}})
    for n in (6, 40):
        edges = np.linspace(0, 200, n + 1)
        segments = pd.DataFrame({
            "recording": "r", "label": [f"s{k:02d}" for k in range(n)],
            "kind": ["static", "phase"] * (n // 2), "start_s": edges[:-1], "end_s": edges[1:],
            "turns": [np.nan, 2.0] * (n // 2),
        })  # fmt: skip
        record = _saved(plot_segments(table, segments, recording="r", title="r"), tmp_path)
        assert legibility_problems(record, min(record["width"], PAGE_WIDTH_PX)) == [], n
