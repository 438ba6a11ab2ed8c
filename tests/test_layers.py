"""The package's layers (docs/architecture.md): every import inside ``imucal``, at module level
or inside a function, goes to the importer's own layer or one below it."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "imucal"

#: The layers from the bottom, each the top-level modules and sub-packages of ``imucal`` in it.
LAYERS = (
    {"constants", "columns", "errormodel", "uncertainty", "modelterms", "calibration",
     "orientation"},
    {"io"},
    {"ingest", "noise", "fleet"},
    {"fits"},
    {"segments", "validation", "sim"},
    {"plots"},
    {"pipeline"},
    {"export"},
    {"gap"},
    {"terms"},
    {"report", "cli"},
)  # fmt: skip
LAYER = {unit: i for i, units in enumerate(LAYERS) for unit in units}


def _module(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path: Path) -> list[tuple[int, str]]:
    """(line, imported module) of every import of ``imucal`` in the file, at any depth."""
    module = _module(path)
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    out = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target == "imucal":  # from imucal import errormodel
                out += [(node.lineno, f"imucal.{a.name}") for a in node.names]
            else:
                out.append((node.lineno, target))
    return [(line, m) for line, m in out if m.split(".")[0] == "imucal"]


def _unit(module: str) -> str | None:
    """The top-level module or sub-package of ``imucal`` a module belongs to (None for the
    package itself)."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else None


def test_every_part_of_the_package_has_a_layer():
    units = {p.stem if p.is_file() else p.name for p in PACKAGE.iterdir()}
    units = {u for u in units if not u.startswith("__") and u not in {"py", "pyi"}}
    assert units - set(LAYER) == set()


def test_no_import_goes_up_a_layer():
    upward = []
    for path in sorted(PACKAGE.rglob("*.py")):
        importer = _unit(_module(path))
        if importer is None:
            continue
        for line, target in _imports(path):
            imported = _unit(target)
            if imported is None or imported == "__version__" or imported == importer:
                continue
            if LAYER[imported] > LAYER[importer]:
                upward.append(f"{path.relative_to(PACKAGE.parent)}:{line} imports {target}")
    assert upward == []
