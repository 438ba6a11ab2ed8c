"""Mutants of a module: the places a small edit can change a result, and the edited source.

Each mutant is one edit at one place of the syntax tree, of the kinds that make the errors
confidence tests must catch: an arithmetic operator swapped (``+``/``-``, ``*``/``/``, ``**``
to ``*``), a comparison moved by its boundary or turned (``<``/``<=``, ``<``/``>``, ``==``/
``!=``), a number moved (an integer by one: a degree of freedom, an index, a window; a float
doubled), a transpose dropped or added (``x.T`` to ``x``, ``a @ b`` to ``a @ b.T``), a sqrt,
abs or sign dropped, ``min``/``max`` swapped, ``and``/``or`` swapped. Docstrings, messages of
raised errors, annotations and decorators are left alone.

The list is ordered and each mutant named ``path:line:col:kind`` so that a fixed random
sample is the same sample on the same code.
"""

from __future__ import annotations

import ast
from dataclasses import dataclass

BINARY = {
    ast.Add: ast.Sub,
    ast.Sub: ast.Add,
    ast.Mult: ast.Div,
    ast.Div: ast.Mult,
    ast.FloorDiv: ast.Div,
    ast.Pow: ast.Mult,
}
COMPARE = {
    ast.Lt: ast.LtE,
    ast.LtE: ast.Lt,
    ast.Gt: ast.GtE,
    ast.GtE: ast.Gt,
    ast.Eq: ast.NotEq,
    ast.NotEq: ast.Eq,
}
TURN = {ast.Lt: ast.Gt, ast.LtE: ast.GtE, ast.Gt: ast.Lt, ast.GtE: ast.LtE}
DROPPED_CALLS = {"sqrt", "abs", "fabs"}
SWAPPED_CALLS = {"min": "max", "max": "min", "minimum": "maximum", "maximum": "minimum"}


@dataclass(frozen=True)
class Mutant:
    """One edit: where (1-based line, 0-based column of the node, end of the node) and what."""

    path: str
    line: int
    col: int
    end_line: int
    end_col: int
    kind: str
    original: str
    replacement: str

    @property
    def name(self) -> str:
        return f"{self.path}:{self.line}:{self.col}:{self.kind}"


def _skipped_spans(tree: ast.AST) -> list[tuple[int, int]]:
    """Line spans never mutated: docstrings, raised errors, annotations, decorators."""
    spans = []
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
                spans.append((body[0].lineno, body[0].end_lineno))
            for d in getattr(node, "decorator_list", []):
                spans.append((d.lineno, d.end_lineno))
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                for a in node.args.args + node.args.kwonlyargs:
                    if a.annotation is not None:
                        spans.append((a.annotation.lineno, a.annotation.end_lineno))
                if node.returns is not None:
                    spans.append((node.returns.lineno, node.returns.end_lineno))
        elif isinstance(node, ast.Raise):
            spans.append((node.lineno, node.end_lineno))
        elif isinstance(node, ast.AnnAssign) and node.value is None:
            spans.append((node.lineno, node.end_lineno))
    return spans


def _inside(node: ast.AST, spans: list[tuple[int, int]]) -> bool:
    return any(a <= node.lineno and node.end_lineno <= b for a, b in spans)


def _in_format(tree: ast.AST) -> set[int]:
    """ids of the nodes inside f-strings (text, not numerics)."""
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.JoinedStr):
            out |= {id(n) for n in ast.walk(node)}
    return out


def _replace(node: ast.AST, **changes) -> str:
    copy = type(node)(**{f: getattr(node, f) for f in node._fields})
    for key, value in changes.items():
        setattr(copy, key, value)
    return "(" + ast.unparse(copy) + ")"


def _edits(node: ast.AST) -> list[tuple[str, str]]:
    """(kind, replacement text) of every mutant of one node."""
    out = []
    if isinstance(node, ast.BinOp):
        new = BINARY.get(type(node.op))
        if new is not None:
            out.append((f"{type(node.op).__name__}->{new.__name__}", _replace(node, op=new())))
        if isinstance(node.op, ast.MatMult):
            right = ast.Attribute(value=node.right, attr="T", ctx=ast.Load())
            out.append(("MatMult->right.T", _replace(node, right=right)))
    elif isinstance(node, ast.AugAssign):
        new = BINARY.get(type(node.op))
        if new is not None:
            out.append((f"Aug{type(node.op).__name__}->{new.__name__}", ""))
    elif isinstance(node, ast.Compare) and len(node.ops) == 1:
        op = type(node.ops[0])
        if op in COMPARE:
            out.append(
                (f"{op.__name__}->{COMPARE[op].__name__}", _replace(node, ops=[COMPARE[op]()]))
            )
        if op in TURN:
            out.append((f"{op.__name__}->{TURN[op].__name__}", _replace(node, ops=[TURN[op]()])))
    elif isinstance(node, ast.Constant) and type(node.value) in (int, float):
        if isinstance(node.value, int):
            out.append(("int+1", repr(node.value + 1)))
        elif node.value != 0:
            out.append(("float*2", repr(node.value * 2)))
        else:
            out.append(("float0->1", "1.0"))
    elif isinstance(node, ast.Attribute) and node.attr == "T":
        out.append(("drop.T", "(" + ast.unparse(node.value) + ")"))
    elif isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
        out.append(("drop-", "(" + ast.unparse(node.operand) + ")"))
    elif isinstance(node, ast.BoolOp):
        new = ast.Or if isinstance(node.op, ast.And) else ast.And
        out.append((f"{type(node.op).__name__}->{new.__name__}", _replace(node, op=new())))
    elif isinstance(node, ast.Call) and node.args and not node.keywords:
        func = node.func
        name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", None)
        if name in DROPPED_CALLS and len(node.args) == 1:
            out.append((f"drop {name}", "(" + ast.unparse(node.args[0]) + ")"))
        if name in SWAPPED_CALLS:
            if isinstance(func, ast.Attribute):
                swapped = ast.Attribute(value=func.value, attr=SWAPPED_CALLS[name], ctx=ast.Load())
            else:
                swapped = ast.Name(id=SWAPPED_CALLS[name], ctx=ast.Load())
            out.append((f"{name}->{SWAPPED_CALLS[name]}", _replace(node, func=swapped)))
    return out


def mutants(path: str, source: str) -> list[Mutant]:
    """Every mutant of a module's source, in source order."""
    tree = ast.parse(source)
    spans = _skipped_spans(tree)
    text = _in_format(tree)
    out = []
    for node in ast.walk(tree):
        if not hasattr(node, "lineno") or id(node) in text or _inside(node, spans):
            continue
        for kind, replacement in _edits(node):
            segment = ast.get_source_segment(source, node)
            if segment is None:
                continue
            if isinstance(node, ast.AugAssign):
                # the operator of ``x += y`` sits between the target and the value
                head = ast.get_source_segment(source, node.target)
                symbol = segment[len(head) :].lstrip().split("=", 1)[0] + "="
                new = BINARY[type(node.op)]
                swapped = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/"}[new] + "="
                replacement = segment.replace(symbol, swapped, 1)
            out.append(
                Mutant(
                    path,
                    node.lineno,
                    node.col_offset,
                    node.end_lineno,
                    node.end_col_offset,
                    kind,
                    segment,
                    replacement,
                )
            )
    return sorted(out, key=lambda m: (m.line, m.col, m.kind))


def apply(source: str, mutant: Mutant) -> str:
    """The source with the mutant's edit made."""
    lines = source.splitlines(keepends=True)
    start = sum(len(x) for x in lines[: mutant.line - 1]) + _byte_col(
        lines[mutant.line - 1], mutant.col
    )
    end = sum(len(x) for x in lines[: mutant.end_line - 1]) + _byte_col(
        lines[mutant.end_line - 1], mutant.end_col
    )
    new = source[:start] + mutant.replacement + source[end:]
    ast.parse(new)  # a mutant must stay valid Python
    return new


def _byte_col(line: str, col: int) -> int:
    """ast's column offsets count UTF-8 bytes; the character index of one."""
    return len(line.encode("utf-8")[:col].decode("utf-8", errors="ignore"))
