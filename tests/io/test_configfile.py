"""The config's check in one paragraph, and the words Snakemake's greedy options swallow."""

from pathlib import Path

import yaml

from imucal.io.configfile import command_line_problem, config_problem, greedy_values

SCHEMA = Path(__file__).resolve().parents[2] / "workflow" / "schemas" / "config.schema.yaml"
RULES = ["all", "ingest", "report", "real"]


def test_the_file_that_sets_a_misspelt_key_is_named(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    base, mine = tmp_path / "config.yaml", tmp_path / "my.yaml"
    base.write_text("datasets:\n  demo: data/demo\n")
    mine.write_text("segmentation:\n  windows_s: 1.0\n")
    config = {**yaml.safe_load(base.read_text()), **yaml.safe_load(mine.read_text())}
    message = config_problem(config, SCHEMA, [base, mine])
    assert message.startswith(
        "my.yaml: key 'segmentation/windows_s' is not a setting, did you mean 'window_s'?"
    )
    assert message.count("\n") == 0
    assert config_problem(yaml.safe_load(base.read_text()), SCHEMA, [base]) is None


def test_a_result_read_as_a_config_by_its_keys(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    result = tmp_path / "cal.json"
    result.write_text('{"format_version": 2, "acc": {}, "gyr": {}}')
    message = config_problem({"acc": {}, "gyr": {}}, SCHEMA, [tmp_path / "config.yaml", result])
    assert message.startswith("cal.json was read as a config file, but it looks like a results")
    assert "its keys (acc, format_version, gyr) are a result's" in message


def test_greedy_options_and_a_swallowed_target():
    argv = ["snakemake", "--cores", "2", "--forcerun", "ingest", "results/d/x.json", "-n"]
    assert greedy_values(argv, ("--forcerun",)) == ["ingest", "results/d/x.json"]
    assert command_line_problem(argv, RULES).startswith("--forcerun took 'results/d/x.json'")
    # the target first, the option joined to its value, a rule target, or rules alone: fine
    for ok in (
        ["snakemake", "results/d/x.json", "--forcerun", "ingest"],
        ["snakemake", "--forcerun=ingest", "results/d/x.json"],
        ["snakemake", "--forcerun", "ingest", "results/d/x.json", "--", "all"],
        ["snakemake", "-R", "ingest", "report"],
        ["snakemake", "--configfile", "my.yaml", "--forcerun", "ingest", "report"],
    ):
        assert command_line_problem(ok, RULES) is None, ok
