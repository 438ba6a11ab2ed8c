"""The effects outside the library: the diagnosis never imports them, the checks render them,
and the check's plan covers each at two magnitudes, alone and beside a library effect."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

from imucal.gap.outside import HARSH, PARTNERS, outside_plan
from imucal.sim.effects import EFFECTS
from imucal.sim.outside import OUTSIDE, make_outside

GAP = Path(__file__).resolve().parents[2] / "imucal" / "gap"
#: The modules that render the checks' hidden sessions: the only ones of the diagnosis's
#: package that may know the outside effects.
RENDERERS = {"blind.py", "outside.py", "stress.py", "detection.py", "checks.py"}


def _imports_outside(path: Path) -> bool:
    for node in ast.walk(ast.parse(path.read_text())):
        names = []
        if isinstance(node, ast.ImportFrom) and node.module:
            names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        if any(n.startswith("imucal.sim.outside") for n in names):
            return True
    return False


def test_no_module_of_the_diagnosis_imports_the_outside_effects():
    offenders = [
        str(p.relative_to(GAP))
        for p in GAP.rglob("*.py")
        if p.name not in RENDERERS and _imports_outside(p)
    ]
    assert offenders == []


def test_diagnosing_a_session_loads_no_outside_effect():
    """The diagnosis's entry points, imported in a fresh interpreter, leave the outside
    package unloaded (nothing they import reaches it)."""
    code = (
        "import sys\n"
        "import imucal.gap.diagnosis, imucal.gap.composite, imucal.gap.static, "
        "imucal.gap.scoring, imucal.gap.catalogue, imucal.terms.loop\n"
        "from imucal.gap.catalogue import catalogue\n"
        "catalogue()\n"
        "print(sorted(m for m in sys.modules if m.startswith('imucal.sim.outside')))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout


def test_outside_effects_are_not_the_librarys():
    assert not set(OUTSIDE) & set(EFFECTS)
    assert len(OUTSIDE) >= 6
    for name in OUTSIDE:
        effect = make_outside(name)
        assert effect.magnitude().value > 0
        scaled = effect.scaled(HARSH)
        assert scaled.magnitude().value == pytest.approx(HARSH * effect.magnitude().value)


def test_the_plan_holds_each_outside_effect_at_two_magnitudes_alone_and_with_a_partner():
    plan = outside_plan(7, n_clean=2)
    assert len({s["name"] for s in plan}) == len(plan) == 2 + 4 * len(OUTSIDE)
    assert set(PARTNERS) == set(OUTSIDE)
    for name in OUTSIDE:
        own = [s for s in plan if s["outside"] == name]
        assert sorted((s["factor"], bool(s["diagnosable"])) for s in own) == [
            (1.0, False), (1.0, True), (HARSH, False), (HARSH, True),
        ]  # fmt: skip
        for s in own:
            assert set(s["diagnosable"]) <= set(EFFECTS)
    assert plan == outside_plan(7, n_clean=2)  # deterministic from the seed
