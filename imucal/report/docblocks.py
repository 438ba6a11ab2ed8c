"""Generated blocks of the docs: text between ``<!-- generated: NAME -->`` and
``<!-- end: NAME -->`` markers, rewritten from a run's output so that no figure is typed by hand.

From the repository root, after the run that writes the text::

    python -m imucal.report.docblocks NAME TEXT_FILE DOC [DOC ...]
"""

from __future__ import annotations

import argparse
from pathlib import Path


def replace_block(path: str | Path, name: str, text: str) -> None:
    """Replace the text between ``<!-- generated: NAME -->`` and ``<!-- end: NAME -->``.

    Raises
    ------
    ValueError
        When ``path`` has no such pair of markers.
    """
    path = Path(path)
    begin, end = f"<!-- generated: {name} -->", f"<!-- end: {name} -->"
    content = path.read_text()
    if begin not in content or end not in content:
        raise ValueError(f"{path}: no block {begin} ... {end}")
    head, rest = content.split(begin, 1)
    _, tail = rest.split(end, 1)
    path.write_text(f"{head}{begin}\n{text.rstrip(chr(10))}\n{end}{tail}")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("name", help="the block's name")
    parser.add_argument("text", type=Path, help="the file whose text the block gets")
    parser.add_argument("docs", type=Path, nargs="+", help="the docs holding the block")
    args = parser.parse_args(argv)
    for doc in args.docs:
        replace_block(doc, args.name, args.text.read_text())
        print(f"{doc}: block {args.name} from {args.text}")


if __name__ == "__main__":
    main()
