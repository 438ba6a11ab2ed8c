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


#: A module holds one concept: past this many lines it holds two (house style).
MAX_MODULE_LINES = 600
#: Past this many lines (docstring included) a function does more than one thing.
MAX_FUNCTION_LINES = 120

#: The modules and functions over their limit when the limits were set, each with its size then:
#: one may shrink below its limit (drop it here) but not grow, and no other may pass it. The
#: diagnosis's (``gap/``) are being regrouped into sub-packages; they may leave this list
#: without it being edited.
KNOWN_OVERSIZE = {
    "imucal/fits/accelerometer.py": 603,
    "imucal/fits/accelerometer.py:fit_cube": 164,
    "imucal/fits/ferraris.py": 618,
    "imucal/fits/ferraris.py:fit_known_orientations": 139,
    "imucal/fits/ferraris.py:fit_known_rotations": 128,
    "imucal/fits/magnetometer.py": 618,
    "imucal/fits/posetopose.py:fit_pose_to_pose": 163,
    "imucal/gap/attribution.py": 848,  # +2: the estimate's flags carried
    "imucal/gap/attribution.py:attribute": 130,  # +1: the estimate's flags carried
    "imucal/gap/locations.py": 690,
    "imucal/gap/motiontwin.py:build_motion_twin": 122,
    "imucal/ingest/summary.py:summarize_recording": 127,
    "imucal/io/orientation.py:read_orientation_reference": 133,
    "imucal/io/raw.py": 644,
    "imucal/pipeline/reference.py": 629,
    "imucal/pipeline/reference.py:fit_gyr_reference": 130,
    "imucal/pipeline/reference.py:validate_references": 130,
    "imucal/segments/filtering.py:lowpass_recording": 125,
    "imucal/segments/ratetable.py:segment_ratetable": 138,
    "imucal/sim/orientation.py:simulate_orientation_session": 172,
    "imucal/terms/poseholdout.py:hold_out_poses": 146,
}
#: The private names one module of the diagnosis takes from another, as above.
KNOWN_PRIVATE = {
    "imucal/gap/statistics.py imports _cube from imucal.gap.locations",
    "imucal/gap/statistics.py imports _gyr_rest from imucal.gap.locations",
    "imucal/gap/statistics.py imports _mag from imucal.gap.locations",
    "imucal/gap/statistics.py imports _noise from imucal.gap.locations",
    "imucal/gap/statistics.py imports _scale from imucal.gap.locations",
    "imucal/gap/statistics.py imports _table from imucal.gap.locations",
    "imucal/gap/statistics.py imports _temperature from imucal.gap.locations",
    "imucal/gap/statistics.py imports _timing from imucal.gap.locations",
    "imucal/gap/statistics.py imports _world_rate from imucal.gap.locations",
}


def _sizes() -> dict[str, int]:
    """Lines of every module and of every function (at any depth) of the package."""
    sizes = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        name = path.relative_to(PACKAGE.parent).as_posix()
        text = path.read_text()
        sizes[name] = len(text.splitlines())
        for node in ast.walk(ast.parse(text, str(path))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                key = f"{name}:{node.name}"
                sizes[key] = max(sizes.get(key, 0), node.end_lineno - node.lineno + 1)
    return sizes


def _is_private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


def _private_uses(path: Path) -> list[str]:
    """Private names the file takes from another module of the package: imported by name, or
    read as an attribute of an imported module (``st._rows``)."""
    tree = ast.parse(path.read_text(), str(path))
    importer = path.relative_to(PACKAGE.parent).as_posix()
    lines = dict(_imports(path))
    modules, uses = {}, []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.lineno in lines:
            target = lines[node.lineno]
            for alias in node.names:
                if _is_private(alias.name):
                    uses.append(f"{importer} imports {alias.name} from {target}")
                modules[alias.asname or alias.name] = f"{target}.{alias.name}"
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == "imucal":
                    modules[alias.asname or alias.name.split(".")[0]] = alias.name
    for node in ast.walk(tree):
        if (
            isinstance(node, ast.Attribute)
            and _is_private(node.attr)
            and isinstance(node.value, ast.Name)
            and node.value.id in modules
        ):
            uses.append(f"{importer} reads {node.value.id}.{node.attr} ({modules[node.value.id]})")
    return uses


def test_no_module_or_function_grows_past_its_limit():
    sizes = _sizes()
    over = {
        key: lines
        for key, lines in sizes.items()
        if lines > (MAX_FUNCTION_LINES if ":" in key else MAX_MODULE_LINES)
    }
    grown = {k: v for k, v in over.items() if v > KNOWN_OVERSIZE.get(k, 0)}
    assert grown == {}, f"over {MAX_MODULE_LINES} lines a module, {MAX_FUNCTION_LINES} a function"
    # a known one that shrank below its limit leaves the list (the diagnosis's may just leave)
    fixed = {k for k in KNOWN_OVERSIZE if k not in over and not k.startswith("imucal/gap/")}
    assert fixed == set(), "no longer over the limit: drop them from KNOWN_OVERSIZE"


def test_no_private_name_is_taken_from_another_module():
    uses = {u for path in sorted(PACKAGE.rglob("*.py")) for u in _private_uses(path)}
    assert uses - KNOWN_PRIVATE == set()


def test_the_checks_of_size_and_private_names_see_what_they_look_for(tmp_path):
    # a private helper read through its module and imported by name are both found
    package = tmp_path / "imucal"
    (package / "gap").mkdir(parents=True)
    (package / "gap" / "use.py").write_text(
        "from imucal.gap import session as st\nfrom imucal.gap.session import _means\n\n"
        "def f(x):\n    return st._rows(x), _means(x)\n"
    )
    global PACKAGE
    saved, PACKAGE = PACKAGE, package
    try:
        uses = _private_uses(package / "gap" / "use.py")
        body = "\n".join(f"    x{i} = {i}" for i in range(MAX_FUNCTION_LINES))
        (package / "long.py").write_text(f"def long():\n{body}\n")
        sizes = _sizes()
    finally:
        PACKAGE = saved
    assert uses == [
        "imucal/gap/use.py imports _means from imucal.gap.session",
        "imucal/gap/use.py reads st._rows (imucal.gap.session)",
    ]
    assert sizes["imucal/long.py:long"] == MAX_FUNCTION_LINES + 1
