"""The figures of the lab report: embedded as ``data:`` URIs, sorted into the report's sections by
their file names, with their captions.
"""

from __future__ import annotations

import base64
import re
from collections.abc import Mapping
from pathlib import Path

#: First word of a figure's file name (before '_' or '-') -> report section. A figure in a
#: folder named ``segments`` belongs to the segmentation whatever its name.
FIGURE_SECTION_BY_PREFIX = {
    "seg": "segmentation",
    "segment": "segmentation",
    "segments": "segmentation",
    "segmentation": "segmentation",
    "mag": "magnetometer",
    "magnetometer": "magnetometer",
    "acc": "accelerometer",
    "accelerometer": "accelerometer",
    "cube": "accelerometer",
    "gyr": "gyroscope",
    "gyro": "gyroscope",
    "gyroscope": "gyroscope",
    "ratetable": "gyroscope",
    "validation": "validation",
    "reference": "validation",
}


#: Folder of the figure captions, one reStructuredText file per figure stem. Snakemake's report
#: (``report(caption=...)`` in the workflow's rules) and the lab report read the same files.
CAPTIONS_DIR = Path(__file__).with_name("captions")


def _read_captions(folder: Path) -> dict[str, str]:
    """File stem -> caption as plain text (reStructuredText's backslash escapes removed)."""
    return {
        path.stem: " ".join(path.read_text(encoding="utf-8").split()).replace("\\", "")
        for path in sorted(folder.glob("*.rst"))
    }


#: Default captions of the figures the stage rules are expected to write (file stem -> text).
#: Any other figure gets a caption made from its file name unless one is passed in.
DEFAULT_CAPTIONS = _read_captions(CAPTIONS_DIR)


_MIME = {".png": "image/png", ".svg": "image/svg+xml"}


_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def embed_figure(path: str | Path) -> str:
    """Return a ``data:`` URI with the PNG or SVG file at ``path`` base64-encoded.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        If the file is neither ``.png`` nor ``.svg``, or a ``.png`` lacks the PNG signature.
    """
    path = Path(path)
    mime = _MIME.get(path.suffix.lower())
    if mime is None:
        raise ValueError(
            f"figure {path} has suffix {path.suffix!r}; expected one of {sorted(_MIME)}"
        )
    if not path.is_file():
        raise FileNotFoundError(f"{path}: figure not found; expected an existing file")
    data = path.read_bytes()
    if mime == "image/png" and not data.startswith(_PNG_SIGNATURE):
        raise ValueError(f"figure {path} does not start with the PNG signature; expected a PNG")
    return f"data:{mime};base64,{base64.b64encode(data).decode('ascii')}"


def figure_section(path: str | Path) -> str:
    """Report section of a figure from its folder and file name (see FIGURE_SECTION_BY_PREFIX)."""
    path = Path(path)
    if path.parent.name == "segments":
        return "segmentation"
    prefix = re.split(r"[_\-.]", path.stem.lower(), maxsplit=1)[0]
    return FIGURE_SECTION_BY_PREFIX.get(prefix, "other")


def figure_caption(path: Path, captions: Mapping[str, str]) -> str:
    stem = path.stem
    if stem in captions:
        return captions[stem]
    if stem in DEFAULT_CAPTIONS:
        return DEFAULT_CAPTIONS[stem]
    words = re.sub(r"[_\-]+", " ", stem).strip()
    if path.parent.name == "segments":
        return f"Segments found in the {words} recording."
    return f"{words[:1].upper()}{words[1:]}."
