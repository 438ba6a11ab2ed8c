"""Every command the README shows works as a new user types it.

Each ``snakemake ...`` command of README.md (fenced ``bash`` blocks and inline code spans) is
dry-run as written, in a fresh working copy of the repository (so that outputs of earlier runs
in the checkout do not change the plan), and the jobs it plans are compared rule by rule with
``PLANS``. A command the README gains without an entry here fails, so does an entry the README
no longer shows. With Snakemake 9 ``--configfile`` and ``--forcerun`` take several values and
swallow a target written after them: such a command plans the whole DAG or fails, and the
comparison catches it. Each ``imucal SUB ...`` command must parse with the package's CLI.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest
import yaml
from snakemake.utils import validate

from imucal.cli import build_parser
from imucal.gap.checks import check_plan

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"
README = REPO / "README.md"

#: What a working copy needs to parse the workflow; results/, reports/ and .snakemake/ stay out.
WORKFLOW_FILES = ("Snakefile", "config", "data", "workflow", "imucal")

#: The config file the README has a user write (`my.yaml`), with its `lab1` on the demo data.
MY_YAML = "datasets:\n  lab1: data/demo\n"

# Jobs (rule -> count) of one dataset with the paper's whole protocol, as the demo plans them;
# calibration.json waits for the diagnosis (the closed loop's terms, config `terms`), which
# reads the reference too.
_CALIBRATION = Counter(
    ingest=5,
    lowpass=1,
    segment=1,
    mag_stages=1,
    acc_stages=1,
    gyr_stages=1,
    gyr_ratetable_stages=1,
    gap_diagnose=1,
    model_terms=1,
    consistency_full=1,
    calibration=1,
)
_DATASET = _CALIBRATION + Counter(
    ingest_summary=1,
    noise=1,
    export=1,
    plot_segments=4,
    phase_figures=1,
    validate=1,
    validation_figures=1,
    stages_full=1,
    stages=1,
    report=1,
)


def _check_jobs(check: str, configfile: str | None = None) -> Counter:
    """The jobs of a check's target: a render and a diagnosis per session of its plan (from the
    config and its schema's defaults, as the workflow plans it), its score and the target."""
    config = yaml.safe_load((REPO / "config" / "config.yaml").read_text())
    if configfile is not None:
        for key, value in yaml.safe_load((REPO / configfile).read_text()).items():
            config.setdefault(key, {}).update(value)
    validate(config, str(REPO / "workflow" / "schemas" / "config.schema.yaml"))
    n = len(check_plan(check, config[check]))
    return Counter({f"{check}_render": n, f"{check}_diagnose": n, f"{check}_score": 1, check: 1})


#: `snakemake --report` reads the outputs of a finished run: in a fresh copy it must stop at the
#: first missing annotated output, after parsing the command and the workflow.
NEEDS_FINISHED_RUN = "needs a finished run"

#: README command -> the jobs its dry run plans (rule -> count).
PLANS: dict[str, Counter | str] = {
    "snakemake --cores 2": _DATASET + Counter(all=1),
    # demo and lab1 (both on data/demo): config/config.yaml stays under my.yaml
    "snakemake --cores 2 --configfile my.yaml": _DATASET + _DATASET + Counter(all=1),
    "snakemake --cores 2 results/lab1/calibration.json --configfile my.yaml": _CALIBRATION,
    # the ingest stage of demo alone, not the DAG below `all`
    "snakemake --cores 2 results/demo/ingest/summary.json --forcerun ingest": Counter(
        ingest=5, ingest_summary=1
    ),
    "snakemake --cores 2 results/demo/calibrated/static.parquet": _CALIBRATION
    + Counter(apply_calibration=1),
    # nine datasets of eight public recordings, all on the partial path, each with its
    # calibration checked on independent parts and shipped at results/NAME/calibration.json (the
    # table of the checks); four have a rest the noise stage analyses (noise, export); BROAD's
    # two trials carry an orientation reference each; the CATS tag's declared poses with a
    # temperature channel get the temperature hold-out
    "snakemake --cores 2 real": Counter(
        ingest=14,
        ingest_summary=9,
        segment=9,
        plot_segments=14,
        partial=9,
        consistency_partial=9,
        calibration_partial=9,
        consistency_table=1,
        noise=4,
        export=4,
        gap_diagnose_partial=9,
        stages=9,
        report=9,
        ingest_orientation=2,
        validate_references=1,
        temperature_holdout=1,
        real=1,
    ),
    "snakemake --cores 2 blind": _check_jobs("blind"),
    "snakemake --cores 2 stress": _check_jobs("stress"),
    "snakemake --cores 2 outside": _check_jobs("outside"),
    "snakemake --cores 2 gap_checks": _check_jobs("blind")
    + _check_jobs("stress")
    + _check_jobs("outside")
    - Counter(blind=1, stress=1, outside=1)
    + Counter(gap_checks_summary=1, gap_checks=1),
    "snakemake --cores 2 detection": _check_jobs("detection"),
    # 200 simulated sessions in chunks of 20, clean and with simulator effects
    "snakemake --cores 1 uncertainty_benchmark": Counter(
        uncertainty_chunk=20, uncertainty_table=2, uncertainty_benchmark=1
    ),
    # 200 simulated sessions of each of the six partial protocols, in chunks of 20
    "snakemake --cores 2 uncertainty_partial": Counter(
        uncertainty_chunk=60, uncertainty_table=1, uncertainty_partial=1
    ),
    "snakemake --report report.zip": NEEDS_FINISHED_RUN,
    # the SLURM profile plans the default DAG (each rule a cluster job)
    "snakemake --profile workflow/profiles/slurm": _DATASET + Counter(all=1),
}

#: Commands the README gives in parts ("`snakemake --cores 2 detection` ... or a reduced grid
#: with `--configfile config/detection_laptop.yaml`"), as a user puts them together.
COMPOSED_PLANS: dict[str, Counter | str] = {
    "snakemake --cores 2 detection --configfile config/detection_laptop.yaml": _check_jobs(
        "detection", "config/detection_laptop.yaml"
    ),
}

#: Commands that read ../shared/data/real, skipped when it is absent.
NEEDS_REAL = {"snakemake --cores 2 real"}


def _readme_commands(program: str) -> list[str]:
    """Commands starting with `program` in README.md, fenced bash blocks first, then inline."""
    text = README.read_text(encoding="utf-8")
    commands = []
    for block in re.findall(r"^```bash\n(.*?)^```", text, flags=re.DOTALL | re.MULTILINE):
        for line in block.splitlines():
            for part in line.split("&&"):
                if part.strip().startswith(program + " "):
                    commands.append(part.strip())
    prose = re.sub(r"^```.*?^```", "", text, flags=re.DOTALL | re.MULTILINE)
    for span in re.findall(r"`([^`]+)`", prose):
        span = " ".join(span.split())  # a span may wrap over lines
        if span.startswith(program + " "):
            commands.append(span)
    return list(dict.fromkeys(commands))


SNAKEMAKE_COMMANDS = _readme_commands("snakemake")
IMUCAL_COMMANDS = _readme_commands("imucal")


def _working_copy(root: Path) -> Path:
    """A fresh working copy (symlinks) of the workflow, with ../shared beside it if present."""
    copy = root / "repo"
    copy.mkdir()
    for name in WORKFLOW_FILES:
        (copy / name).symlink_to(REPO / name)
    (copy / "my.yaml").write_text(MY_YAML, encoding="utf-8")
    if SHARED.is_dir():
        (root / "shared").symlink_to(SHARED)
    return copy


def _dry_run(command: str, root: Path) -> subprocess.CompletedProcess:
    """Dry-run a snakemake command as typed, in a working copy under `root`."""
    argv = shlex.split(command)
    assert argv[0] == "snakemake"
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    return subprocess.run(
        [sys.executable, "-m", "snakemake", *argv[1:], "--dry-run", "--quiet", "rules"],
        cwd=_working_copy(root),
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )


def _planned_jobs(output: str) -> Counter:
    """The first `Job stats` table of a dry run as rule -> count."""
    lines = output.splitlines()
    start = lines.index("Job stats:") + 3  # title, header, dashes
    jobs = Counter()
    for line in lines[start:]:
        rule, count = line.split()
        if rule == "total":
            assert sum(jobs.values()) == int(count)
            return jobs
        jobs[rule] = int(count)
    raise AssertionError(f"no total in the job stats of:\n{output}")


@pytest.fixture(scope="module")
def dry_runs(tmp_path_factory) -> dict[str, subprocess.CompletedProcess]:
    """Dry runs of every known command, side by side (each parses the Snakefile, ~3-10 s)."""
    commands = [
        c for c in {**PLANS, **COMPOSED_PLANS} if c not in NEEDS_REAL or _real_data_present()
    ]
    roots = {c: tmp_path_factory.mktemp("readme") for c in commands}
    with ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as pool:
        results = pool.map(lambda c: _dry_run(c, roots[c]), commands)
        return dict(zip(commands, results))


def _real_data_present() -> bool:
    return (SHARED / "data" / "real").is_dir()


def test_readme_shows_commands():
    # the extraction itself: the quickstart block, the my.yaml block and the inline spans
    assert "snakemake --cores 2" in SNAKEMAKE_COMMANDS
    assert "snakemake --cores 2 --configfile my.yaml" in SNAKEMAKE_COMMANDS
    assert "snakemake --cores 2 detection" in SNAKEMAKE_COMMANDS
    assert {c.split()[1] for c in IMUCAL_COMMANDS} >= {"simulate", "apply", "export"}


def test_every_readme_command_has_a_plan():
    unknown = [c for c in SNAKEMAKE_COMMANDS if c not in PLANS]
    stale = [c for c in PLANS if c not in SNAKEMAKE_COMMANDS]
    assert not unknown, f"README commands without an entry in PLANS (add their jobs): {unknown}"
    assert not stale, f"PLANS entries the README no longer shows: {stale}"


@pytest.mark.slow  # ~11 dry runs of 4-12 s each: ~80 s of CPU in all, run two at a time
@pytest.mark.parametrize("command", list({**PLANS, **COMPOSED_PLANS}))
def test_command_plans_expected_jobs(command, dry_runs):
    if command in NEEDS_REAL and not _real_data_present():
        pytest.skip(f"public recordings not found at {SHARED / 'data' / 'real'} (../shared absent)")
    expected = {**PLANS, **COMPOSED_PLANS}[command]
    result = dry_runs[command]
    output = result.stdout + result.stderr
    if expected == NEEDS_FINISHED_RUN:
        assert result.returncode != 0
        assert re.search(r"File \S+ marked for report but does not exist", output), output
        return
    assert result.returncode == 0, output
    assert _planned_jobs(output) == expected


@pytest.mark.parametrize("command", IMUCAL_COMMANDS)
def test_imucal_command_parses(command):
    argv = shlex.split(command)[1:]
    if argv[0].startswith("--"):  # an option of the program itself, e.g. --version
        run = subprocess.run(
            [sys.executable, "-m", "imucal.cli", *argv],
            env={**os.environ, "PYTHONPATH": str(REPO)},
            capture_output=True,
            text=True,
            check=False,
        )
        assert run.returncode == 0 and run.stdout.startswith("imucal "), run.stderr
        return
    help_run = subprocess.run(
        [sys.executable, "-m", "imucal.cli", argv[0], "--help"],
        env={**os.environ, "PYTHONPATH": str(REPO)},
        capture_output=True,
        text=True,
        check=False,
    )
    assert help_run.returncode == 0, help_run.stderr
    assert help_run.stdout.startswith(f"usage: imucal {argv[0]}")
    if len(argv) == 1:
        return  # named without arguments, as in "rendered by `imucal simulate`"
    # the arguments shown parse; `a|b|c` stands for each of its choices
    variants = [[]]
    for arg in argv:
        variants = [v + [choice] for v in variants for choice in arg.split("|")]
    for variant in variants:
        args = build_parser().parse_args(variant)
        assert args.command == argv[0]
