"""The workflow's config files checked against their schema, with errors that fit on a screen.

Snakemake's ``validate`` prints the whole schema when a config breaks it. :func:`config_problem`
finds the same errors first (the schema's JSON-schema validator) and says each in one
paragraph: the config file that sets the key, the key's path, the closest known key
("did you mean") and the known keys there, or what a wrong value should be. It also tells a
results file read as a config file (Snakemake's ``--configfile`` takes every word after it, so a
target written after it is read as one) from a mistyped config. :func:`command_line_problem`
tells the same of a target swallowed by ``--forcerun``, which would otherwise plan the whole
workflow.
"""

from __future__ import annotations

import difflib
import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import jsonschema
import yaml

#: Options of Snakemake's command line that take every word after them (argparse ``nargs``).
GREEDY_OPTIONS = ("--forcerun", "-R", "--configfile", "--configfiles")
#: Keys of the workflow's result files (calibration.json, the stage results, diagnosis.json):
#: a config holding them at its top is a result read as a config file.
RESULT_KEYS = frozenset(
    {"format_version", "acc", "gyr", "mag", "convention", "frame", "missing", "stages",
     "recordings", "gap", "effects", "explained", "not_run", "sensors", "terms"}
)  # fmt: skip


def _load(path: Path) -> Any:
    text = path.read_text(encoding="utf-8")
    return json.loads(text) if path.suffix.lower() == ".json" else yaml.safe_load(text)


def _holds(tree: Any, keys: Sequence) -> bool:
    for key in keys:
        if not isinstance(tree, Mapping) or key not in tree:
            return False
        tree = tree[key]
    return True


def _shown(path: Path) -> str:
    """A path as the user wrote it: relative to the working directory when inside it."""
    try:
        return str(path.resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(path)


def _source(files: Sequence[Path], keys: Sequence) -> str:
    """The last config file that sets ``keys`` (later files override earlier ones)."""
    for path in reversed(files):
        try:
            if _holds(_load(path), keys):
                return _shown(path)
        except (OSError, ValueError, yaml.YAMLError):
            continue
    return "the config"


def _result_file(path: Path) -> str | None:
    """Why a config file is a results file of the workflow, or None."""
    parts = path.parts
    if path.suffix.lower() in (".parquet", ".html", ".csv", ".tsv", ".png"):
        return f"its suffix is {path.suffix} (config files are YAML or JSON)"
    if "results" in parts or "reports" in parts:
        return "it lies under results/ or reports/"
    try:
        content = _load(path)
    except (OSError, ValueError, yaml.YAMLError):
        return None
    if isinstance(content, Mapping) and len(RESULT_KEYS & set(content)) >= 2:
        return f"its keys ({', '.join(sorted(RESULT_KEYS & set(content)))}) are a result's"
    return None


def _key(path: Sequence) -> str:
    return "/".join(str(p) for p in path)


def _unknown_key(
    err: jsonschema.ValidationError, files: Sequence[Path], elsewhere: Sequence[str] = ()
) -> str | None:
    known = sorted(err.schema.get("properties", {}))
    extra = [k for k in err.instance if k not in known]
    if not extra:
        return None
    where = _key(err.absolute_path)
    parts = []
    for key in extra:
        path = [*err.absolute_path, key]
        close = difflib.get_close_matches(str(key), known, n=1, cutoff=0.6)
        hint = f", did you mean {close[0]!r}?" if close else "."
        parts.append(f"{_source(files, path)}: key {_key(path)!r} is not a setting{hint}")
    scope = f"of {where!r}" if where else "at the top level"
    declared = (
        "each declared with its default and unit by its model term, docs/model-terms.md"
        if err.absolute_path and err.absolute_path[0] in elsewhere
        else "each with its default and unit in workflow/schemas/config.schema.yaml"
    )
    return f"{' '.join(parts)} Settings {scope}: {', '.join(known)} ({declared})."


def _wrong_value(err: jsonschema.ValidationError, files: Sequence[Path]) -> str:
    path = list(err.absolute_path)
    described = err.schema.get("description") if isinstance(err.schema, Mapping) else None
    value = json.dumps(err.instance, default=str)
    value = value if len(value) <= 60 else value[:57] + "..."
    rule = f"{err.validator} {json.dumps(err.validator_value, default=str)}"
    rule = rule if len(rule) <= 80 else str(err.validator)
    expected = f" Expected: {described}." if described else ""
    return (
        f"{_source(files, path)}: key {_key(path) or '(top level)'!r}: {value} breaks the "
        f"schema's {rule!r}.{expected} Fix the file and run again."
    )


def config_problem(
    config: Mapping,
    schema_path: str | Path,
    files: Sequence[str | Path] = (),
    sections: Mapping[str, Mapping] | None = None,
) -> str | None:
    """What is wrong with a config against its schema, in one paragraph, or None.

    Parameters
    ----------
    config : mapping
        The merged config (Snakemake's ``config``).
    schema_path : path
        The JSON-schema YAML (``workflow/schemas/config.schema.yaml``).
    files : sequence of path
        The config files merged into ``config``, in order (the workflow's own first); the
        message names the one that sets the offending key.
    sections : mapping, optional
        Top-level section -> its schema, for sections whose schema is made elsewhere (the
        model terms' ``terms``, :func:`imucal.modelterms.registry.settings_schema`); they
        replace the file's.

    Returns
    -------
    str or None
        None for a valid config; else the file, the key, the closest known key or the value
        expected, and the fix.
    """
    files = [Path(f) for f in files]
    results = {path: _result_file(path) for path in files}
    for path, why in results.items():
        if why:
            configs = " ".join(_shown(p) for p, w in results.items() if not w and p != files[0])
            target = _shown(path)
            return (
                f"{target} was read as a config file, but it looks like a results file ({why}): "
                "Snakemake's --configfile takes every word after it, so a target written "
                "after it is read as a config file. Write the target before the option "
                f"(snakemake --cores 2 {target} --configfile {configs or 'my.yaml'}) or join "
                f"the option to its value (--configfile={configs or 'my.yaml'} {target})."
            )
    schema = yaml.safe_load(Path(schema_path).read_text(encoding="utf-8"))
    schema["properties"].update(dict(sections or {}))
    validator = jsonschema.validators.validator_for(schema)(schema)
    errors = sorted(validator.iter_errors(dict(config)), key=lambda e: list(e.absolute_path))
    if not errors:
        return None
    unknown = [e for e in errors if e.validator == "additionalProperties" and
               isinstance(e.instance, Mapping)]  # fmt: skip
    for err in unknown:
        text = _unknown_key(err, files, list(sections or {}))
        if text:
            return text
    return _wrong_value(jsonschema.exceptions.best_match(errors), files)


def greedy_values(argv: Sequence[str], options: Sequence[str]) -> list[str]:
    """The words Snakemake's command line gives to ``options`` (each takes every word after
    it up to the next option; ``--option=value`` takes its value alone)."""
    values, taking = [], False
    for word in argv[1:]:
        if word.startswith("-"):
            name, _, value = word.partition("=")
            taking = name in options and not value
            if name in options and value:
                values.append(value)
            continue
        if taking:
            values.append(word)
    return values


def command_line_problem(argv: Sequence[str], rule_names: Sequence[str]) -> str | None:
    """A target swallowed by ``--forcerun``: a word after it that is a file of the workflow, not
    a rule, while the command names no target, so the whole workflow would be planned.

    Parameters
    ----------
    argv : sequence of str
        The command line (``sys.argv``).
    rule_names : sequence of str
        The workflow's rules.

    Returns
    -------
    str or None
        The message with the fix, or None.
    """
    forced = greedy_values(argv, ("--forcerun", "-R"))
    files = [w for w in forced if w not in rule_names and ("/" in w or "." in w)]
    if not files:
        return None
    consumed = set(greedy_values(argv, GREEDY_OPTIONS))
    targets = [w for w in argv[1:] if not w.startswith("-") and w not in consumed]
    if any(t in rule_names or "/" in t or "." in t for t in targets):
        return None
    rules = [w for w in forced if w in rule_names]
    example = f"snakemake --cores 2 {files[0]} --forcerun {' '.join(rules) or 'RULE'}"
    return (
        f"--forcerun took {', '.join(repr(f) for f in files)} as a file to rerun, not as a "
        "target: Snakemake's --forcerun takes every word after it, so this command names no "
        f"target and would plan the whole workflow. Write the target first ({example}) or "
        f"join the option to its value (--forcerun={rules[0] if rules else 'RULE'} {files[0]})."
    )
