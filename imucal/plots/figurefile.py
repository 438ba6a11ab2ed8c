"""A figure as a PNG file that carries the record of its texts, and the legibility check that
reads it.

:func:`save_figure` is the one way a figure of the pipeline reaches a file: it saves at
:data:`~imucal.plots.style.FIGURE_DPI` and writes into the PNG (an ``iTXt`` chunk,
:data:`TEXT_KEY`) every text line as it was drawn: its string, its font size in points and its
box (the four corners of its rotated rectangle, PNG pixels, y down), taken from the renderer's
own calls, so texts that are not drawn (ticks outside the view) are not in it. A page that
shows the figure ``d`` px wide renders a text of ``s`` pt at ``s / 72 * dpi * d / width`` px;
:func:`legibility_problems` lists the texts below a size and the pairs of texts that overlap.
"""

from __future__ import annotations

import io
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from imucal.plots.style import FIGURE_DPI, MIN_TEXT_PX

if TYPE_CHECKING:
    from matplotlib.figure import Figure

#: Key of the PNG text chunk that holds the record of a figure's texts (JSON).
TEXT_KEY = "imucal:texts"
#: Overlap (px, in the saved image) two texts' boxes may share before they count as
#: overlapping: antialiasing and the glyphs' side bearings touch at less.
OVERLAP_TOLERANCE_PX = 1.0


@dataclass(frozen=True)
class DrawnText:
    """One line of text as drawn.

    Attributes
    ----------
    text : str
    size_pt : float
        Font size, points.
    corners : tuple
        The rotated rectangle of the line (from the descent to the ascent of its glyphs),
        four (x, y) corners in pixels of the saved image, y down.
    """

    text: str
    size_pt: float
    corners: tuple


def _recording_renderer(width: float, height: float, dpi: float, out: list):
    """An Agg renderer that records every text line it draws into ``out``."""
    from matplotlib.backends.backend_agg import RendererAgg

    class Recording(RendererAgg):
        def draw_text(self, gc, x, y, s, prop, angle, ismath=False, mtext=None):
            # (x, y): the start of the line's baseline, y down (Agg's flipped axis); the
            # line is turned by ``angle`` degrees counter-clockwise about it
            w, h, d = self.get_text_width_height_descent(s, prop, ismath)
            if str(s).strip():
                a = np.deg2rad(angle)
                along = np.array([np.cos(a), -np.sin(a)])  # y down
                up = np.array([-np.sin(a), -np.cos(a)])
                base = np.array([x, y], dtype=float)
                corners = [base - d * up, base + w * along - d * up,
                           base + w * along + (h - d) * up, base + (h - d) * up]  # fmt: skip
                out.append(
                    DrawnText(
                        str(s), float(prop.get_size_in_points()),
                        tuple(tuple(round(float(v), 1) for v in c) for c in corners),
                    )
                )  # fmt: skip
            return super().draw_text(gc, x, y, s, prop, angle, ismath, mtext)

    return Recording(width, height, dpi)


def drawn_texts(fig: Figure, dpi: float = FIGURE_DPI) -> list[DrawnText]:
    """Every text line of ``fig`` as it is drawn at ``dpi`` (the figure is laid out, not saved).

    Returns
    -------
    list of DrawnText
        In drawing order.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    if not isinstance(fig.canvas, FigureCanvasAgg):
        FigureCanvasAgg(fig)
    old = fig.dpi
    fig.dpi = dpi
    try:
        width, height = (fig.get_size_inches() * dpi).round().astype(int)
        texts: list[DrawnText] = []
        fig.draw(_recording_renderer(width, height, dpi, texts))
    finally:
        fig.dpi = old
    return texts


def save_figure(fig: Figure, path: str | Path, dpi: float = FIGURE_DPI) -> Path:
    """Save ``fig`` as PNG at ``dpi`` with the record of its texts (:data:`TEXT_KEY`).

    Returns
    -------
    Path
        The file written (its folder is created).
    """
    path = Path(path)
    if path.suffix.lower() != ".png":
        raise ValueError(f"{path}: a figure is saved as .png; got {path.suffix!r}")
    texts = drawn_texts(fig, dpi)
    record = {
        "dpi": dpi,
        "texts": [{"text": t.text, "pt": t.size_pt, "corners": t.corners} for t in texts],
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi, metadata={TEXT_KEY: json.dumps(record, ensure_ascii=False)})
    return path


def read_text_record(png: bytes) -> dict:
    """The text record of a PNG written by :func:`save_figure`.

    Returns
    -------
    dict
        ``dpi``, ``width`` and ``height`` (pixels) and ``texts`` (``text``, ``pt``,
        ``corners``).

    Raises
    ------
    ValueError
        If the PNG has no record (it was not saved by :func:`save_figure`).
    """
    from PIL import Image

    with Image.open(io.BytesIO(png)) as image:
        text = dict(getattr(image, "text", {}) or {})
        width, height = image.size
    if TEXT_KEY not in text:
        raise ValueError(
            f"the PNG has no {TEXT_KEY!r} record of its texts; expected a figure saved by "
            "imucal.plots.figurefile.save_figure"
        )
    return {**json.loads(text[TEXT_KEY]), "width": width, "height": height}


def _overlap(a: np.ndarray, b: np.ndarray, tolerance: float) -> bool:
    """Whether two convex quadrilaterals overlap by more than ``tolerance`` px (separating
    axes: the four edge normals of each)."""
    for quad in (a, b):
        for k in range(4):
            edge = quad[(k + 1) % 4] - quad[k]
            n = np.array([-edge[1], edge[0]])
            length = np.hypot(*n)
            if length == 0:
                continue
            n /= length
            pa, pb = a @ n, b @ n
            if min(pa.max(), pb.max()) - max(pa.min(), pb.min()) <= tolerance:
                return False
    return True


def legibility_problems(
    record: Mapping, shown_width_px: float, min_px: float = MIN_TEXT_PX
) -> list[str]:
    """What makes a figure hard to read where it is shown ``shown_width_px`` wide: its texts
    rendered below ``min_px`` and the pairs of texts whose boxes overlap.

    Parameters
    ----------
    record : mapping
        :func:`read_text_record`'s record.
    shown_width_px : float
        The width the page shows the image at (CSS px).
    min_px : float
        Smallest font size as rendered (CSS px).

    Returns
    -------
    list of str
        One line per problem; empty for a legible figure.
    """
    scale = float(shown_width_px) / float(record["width"])
    px_per_pt = float(record["dpi"]) / 72.0 * scale
    problems = [
        f"{t['text']!r}: {t['pt']:g} pt renders at {t['pt'] * px_per_pt:.1f} px (< {min_px:g})"
        for t in record["texts"]
        if t["pt"] * px_per_pt < min_px
    ]
    quads = [np.asarray(t["corners"], dtype=float) for t in record["texts"]]
    for i, j in _pairs(quads):
        if _overlap(quads[i], quads[j], OVERLAP_TOLERANCE_PX):
            problems.append(
                f"{record['texts'][i]['text']!r} overlaps {record['texts'][j]['text']!r}"
            )
    return problems


def _pairs(quads: Sequence[np.ndarray]):
    """Index pairs of quadrilaterals whose bounding boxes meet (the candidates for overlap)."""
    if not quads:
        return
    low = np.array([q.min(axis=0) for q in quads])
    high = np.array([q.max(axis=0) for q in quads])
    for i in range(len(quads)):
        meet = np.all((low[i + 1 :] < high[i]) & (high[i + 1 :] > low[i]), axis=1)
        for j in np.nonzero(meet)[0]:
            yield i, i + 1 + int(j)
