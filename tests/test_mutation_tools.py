"""The mutation runner's own parts: the mutants it makes, the changed functions it finds."""

from __future__ import annotations

import ast
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent / "mutation"))

from mutants import apply, mutants  # noqa: E402
from run import changed_functions, targets  # noqa: E402

SOURCE = '''"""Docstring 1.0."""


def f(x, n):
    """Not mutated: 2."""
    if n < 3:
        raise ValueError(f"n is {n}, expected at least 3")
    dof = n - 1
    s = np.sqrt(x @ x.T / dof)
    s += 1.5
    return max(s, -x.sum())
'''


def test_every_mutant_is_one_edit_of_the_code_and_none_of_the_text():
    found = mutants("m.py", SOURCE)
    kinds = {m.kind for m in found}
    assert {"Lt->LtE", "Lt->Gt", "int+1", "Sub->Add", "drop sqrt", "drop.T", "MatMult->right.T",
            "float*2", "AugAdd->Sub", "max->min", "drop-", "Div->Mult"} <= kinds  # fmt: skip
    for m in found:
        new = apply(SOURCE, m)
        ast.parse(new)
        assert new != SOURCE and "Docstring 1.0" in new and "Not mutated: 2." in new
        assert "expected at least 3" in new  # messages are left alone
    assert not [m for m in found if m.line in (1, 5, 7)]
    assert apply(SOURCE, next(m for m in found if m.kind == "AugAdd->Sub")).count("s -= 1.5") == 1
    names = [m.name for m in found]
    assert len(names) == len(set(names))


def test_changed_functions_are_the_innermost_spans_of_the_changed_lines():
    assert changed_functions(SOURCE, {8}) == [(4, 11)]
    assert changed_functions(SOURCE, {2}) == [(1, 10**9)]


def test_every_module_of_the_core_has_tests_that_exist():
    root = Path(__file__).resolve().parents[1]
    for path in ("imucal/fits/reference.py", "imucal/pipeline/stages/common.py",
                 "imucal/terms/poseholdout.py", "imucal/uncertainty.py"):  # fmt: skip
        tests = targets(path)
        assert tests and all((root / t.split("::")[0]).exists() for t in tests), path
