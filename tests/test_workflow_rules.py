"""The workflow's rules keep to the habits of the Snakemake workflows catalogue.

Read as text: no ``lambda`` in a rule (input and param functions have names and docstrings in
``workflow/rules/{datasets,inputs,targets,checks}.smk``), no whole ``config`` handed to a rule
(a changed setting would rerun every rule that takes it), no git call and no planning of the
checks' sessions when the workflow is parsed (both are done where they are needed), and every
script that reads ``dataset.yaml`` declares it as an input.
"""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RULE_FILES = [ROOT / "Snakefile", *sorted((ROOT / "workflow" / "rules").glob("*.smk"))]
SCRIPTS = sorted((ROOT / "workflow" / "scripts").glob("*.py"))


def _lines(path: Path):
    for number, line in enumerate(path.read_text().splitlines(), 1):
        if not line.lstrip().startswith("#"):
            yield number, line


def test_no_lambda_in_the_rules() -> None:
    hits = [f"{p.name}:{n}" for p in RULE_FILES for n, line in _lines(p) if "lambda" in line]
    assert hits == []


def test_no_rule_takes_the_whole_config() -> None:
    whole = re.compile(r"=\s*config\s*,?\s*$")
    hits = [f"{p.name}:{n}" for p in RULE_FILES for n, line in _lines(p) if whole.search(line)]
    assert hits == []


def test_nothing_runs_git_or_plans_the_checks_at_parse_time() -> None:
    top_level_call = re.compile(r"^[A-Za-z_][\w.]*\s*=\s*\w*(plan|_commit|subprocess)\w*\(")
    hits = [
        f"{p.name}:{n}"
        for p in RULE_FILES
        for n, line in _lines(p)
        if top_level_call.search(line) or "subprocess" in line or '"git"' in line
    ]
    assert hits == []


def test_scripts_that_read_dataset_yaml_declare_it_as_an_input() -> None:
    for script in SCRIPTS:
        text = script.read_text()
        for call in re.findall(r"read_dataset\(([^\n]*)\)", text):
            assert "snakemake.input" in call, f"{script.name}: read_dataset({call})"
