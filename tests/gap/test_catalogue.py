"""The catalogue of effects: every effect of the simulator has one spec, which states for every
scope of the diagnosis an estimator or the reason that scope cannot observe it, and every model
term answers an effect the protocol's diagnosis estimates."""

from __future__ import annotations

import dataclasses

import pytest

from imucal.gap import catalogue
from imucal.gap.library import (
    KINDS,
    SCOPES,
    not_observable,
    register,
    registered_specs,
    scope_library,
    spec_of,
    unregister,
)
from imucal.modelterms import term_class, term_names
from imucal.sim.effects import EFFECTS


@pytest.fixture
def specs_restored():
    """The registry as it was, in its order, after the test."""
    before = registered_specs()
    yield
    for spec in registered_specs():
        unregister(spec.name)
    for spec in before:
        register(spec)


def test_every_effect_has_an_estimator_or_a_reason_in_every_scope():
    assert catalogue.contract_violations() == []
    entries = catalogue.catalogue()
    assert set(entries) == set(EFFECTS)
    for entry in entries.values():
        assert set(entry.estimated) | set(entry.not_observable) == set(SCOPES)
        assert not set(entry.estimated) & set(entry.not_observable)
        assert all(entry.not_observable.values()), entry.name
        assert entry.kind in KINDS and entry.description, entry.name


def test_every_scope_table_is_read_from_the_specs():
    for scope in SCOPES:
        library, reasons = scope_library(scope), not_observable(scope)
        assert set(library) | set(reasons) == set(EFFECTS) and not set(library) & set(reasons)
        for name, model in library.items():
            assert model is spec_of(name).model(scope) and model.name == name
        for name, reason in reasons.items():
            assert reason == spec_of(name).reason(scope)


def test_a_spec_without_a_scope_is_refused_and_named():
    lever = spec_of("lever_arm")
    scopes = {k: v for k, v in lever.scopes.items() if k != "static"}
    broken = dataclasses.replace(lever, name="lever_arm_2", scopes=scopes)
    with pytest.raises(ValueError, match="static: 'lever_arm_2' has neither an estimator"):
        register(broken)
    with pytest.raises(ValueError, match="kind 'noisy' is not one of"):
        register(dataclasses.replace(lever, name="lever_arm_2", kind="noisy"))
    with pytest.raises(ValueError, match="has the model of 'lever_arm'"):
        register(dataclasses.replace(lever, name="lever_arm_2"))
    with pytest.raises(ValueError, match="registered already"):
        register(lever)


def test_the_contract_names_an_effect_without_a_spec_and_a_spec_without_an_effect(
    specs_restored,
):
    lever = spec_of("lever_arm")
    unregister("lever_arm")
    reasons = {scope: "a reason for nothing" for scope in SCOPES}
    register(dataclasses.replace(lever, name="no_such_effect", scopes=reasons))
    problems = catalogue.contract_violations()
    assert "'lever_arm': an effect of the simulator without a spec" in problems
    assert "protocol: 'lever_arm' is listed (LISTING) but has no spec" in problems
    assert "'no_such_effect': a spec of no effect of the simulator" in problems
    assert "lever_arm" not in scope_library("protocol")
    assert not_observable("static")["no_such_effect"] == "a reason for nothing"


@pytest.mark.parametrize("term", term_names())
def test_every_model_term_answers_an_effect_the_protocol_estimates(term):
    effect = term_class(term).effect
    entry = catalogue.catalogue()[effect]
    assert entry.term == term and "protocol" in entry.estimated


def test_the_docs_show_which_rules_bind_each_effect_as_the_specs_say():
    from pathlib import Path

    from imucal.gap.library.rules import rules_table

    text = (Path(__file__).resolve().parents[2] / "docs" / "gap.md").read_text()
    begin, end = "<!-- generated: effect-rules -->\n", "<!-- end: effect-rules -->"
    shown = text[text.index(begin) + len(begin) : text.index(end)]
    assert shown == rules_table(), "rerun: python -m imucal.gap.library.rules"
