"""Which acceptance rules each effect of the library must pass, as a table.

Every effect passes the common rules of an explanation (docs/gap.md, "What an explanation must
pass": beyond its null on its own side, judged where it acts, no structured residual where it
acts, ranked on the same held-out data). What binds an effect beyond those is read from its
spec: a ``spread`` effect's widening of the null counts at its own signature only, and an
effect's physics gate, where its model has one, tests the shape a flexible fit cannot fake.
docs/gap.md shows the table this module renders (``python -m imucal.gap.library.rules``); a
test holds the two equal.
"""

from __future__ import annotations

from imucal.gap.library.registry import registered_specs
from imucal.gap.library.spec import SCOPES, EffectSpec

#: What binds a ``spread`` effect, whatever its gate.
SPREAD_RULE = "rule 4: its widening of the null counts at its own signature only"

#: What binds an effect without a gate or spread: the common rules alone.
COMMON_RULE = (
    "rules 1-3 and 5 alone: it adds no spread, so it must move the replicas' mean at its own"
    " signature and leave no structured residual there"
)


def _first_sentence(text: str) -> str:
    """The first sentence of a docstring, on one line, without reST markup."""
    flat = " ".join(text.split()).replace("``", "").replace(":data:", "")
    flat = flat.replace("`", "")
    return flat.split(". ")[0].rstrip(".")


def binding_rules(spec: EffectSpec) -> list[str]:
    """The rules beyond the common ones that bind an effect, one phrase each.

    Parameters
    ----------
    spec : EffectSpec

    Returns
    -------
    list of str
        ``SPREAD_RULE`` for a spread effect, then each distinct physics gate of its models
        (scope: the gate's first sentence), else ``COMMON_RULE``; an effect the pipeline's model
        absorbs is said to be reported, never attributed.
    """
    models = [(scope, spec.model(scope)) for scope in SCOPES if spec.model(scope) is not None]
    if models and not any(m.opens_gap for _, m in models):
        return ["reported, never attributed: the pipeline's exact model absorbs it"]
    rules = [SPREAD_RULE] if spec.kind == "spread" else []
    gates: dict = {}
    for scope, model in models:
        if model.gate is not None:
            gates.setdefault(model.gate, []).append(scope)
    for gate, scopes in gates.items():
        reason = _first_sentence(gate.__doc__ or gate.__name__)
        rules.append(f"rule {4 if spec.kind == 'spread' else 6} ({', '.join(scopes)}): {reason}")
    return rules or [COMMON_RULE]


def rules_table() -> str:
    """The markdown table of every registered effect: its kind, the scopes that observe it and
    the rules that bind it (:func:`binding_rules`)."""
    lines = ["| effect | kind | observed in | what binds it beyond the common rules |",
             "|---|---|---|---|"]  # fmt: skip
    for spec in registered_specs():
        scopes = [s for s in SCOPES if spec.model(s) is not None]
        observed = ", ".join(scopes) if scopes else "no scope (simulated only)"
        rules = "; ".join(binding_rules(spec)) if scopes else "-"
        lines.append(f"| `{spec.name}` | {spec.kind} | {observed} | {rules} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    print(rules_table(), end="")
