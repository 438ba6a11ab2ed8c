"""Sampled mutation testing of the numeric core (docs/testing.md, "Mutation testing").

Copies the checkout's tracked files to a scratch folder (never edits the checkout), then for
each mutant of the sample writes the mutated module there, runs the tests that cover its
module (:data:`TARGETS`, the ``slow`` ones left out) until the first failure, and restores the
module. A mutant is *killed* when a test fails, *timeout* (counted as killed: the mutant
loops) when the tests take more than :data:`TIMEOUT_S`, else it *survived*. ``--check`` first
runs each module's tests on the unmutated copy (they must pass, or every mutant would count as
killed). Survivors known to be equivalent are listed with their reason in
``tests/mutation/equivalent.txt`` and scored apart.

Usage (from the repository root)::

    python tests/mutation/run.py --jobs 2 --check            # the sampled run of docs/testing.md
    python tests/mutation/run.py --base main                 # every mutant of the functions
                                                             # changed since main
    python tests/mutation/run.py --module imucal/fits/reference.py --sample 0   # all of one

Results are appended as JSON lines to ``--out`` (one per mutant; by default in the scratch
folder, outside the checkout) and summarised per package; ``summary.py`` tallies a results file
(of a run stopped early too).
"""

from __future__ import annotations

import argparse
import ast
import fnmatch
import json
import os
import queue
import random
import re
import shutil
import subprocess
import sys
import tempfile
import time
from collections import Counter, defaultdict
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from mutants import Mutant, apply, mutants  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
#: The disturbance tests on short recordings (the whole-session ones take minutes each).
DISTURBANCE_UNITS = [
    "tests/gap/test_gap_disturbance.py::test_every_disturbance_has_a_motion_estimator_and_a_static_reason",
    "tests/gap/test_gap_disturbance.py::test_a_world_fixed_field_is_recovered_as_the_field_along_the_path",
    "tests/gap/test_gap_disturbance.py::test_a_hard_iron_on_the_board_or_a_turned_magnetometer_is_not_a_world_fixed_field",
    "tests/gap/test_gap_disturbance.py::test_knocks_are_counted_and_their_peak_measured",
    "tests/gap/test_gap_disturbance.py::test_a_reference_with_heavy_tails_at_fast_motion_has_no_knocks",
    "tests/gap/test_gap_disturbance.py::test_a_vibration_line_is_found_at_its_frequency_and_amplitude",
    "tests/gap/test_gap_disturbance.py::test_a_magnet_fixed_near_the_path_is_found_where_it_is",
]
#: Module pattern -> the test files that cover it (slow tests are deselected).
TARGETS = {
    "imucal/errormodel.py": ["tests/test_errormodel.py"],
    "imucal/uncertainty.py": ["tests/test_uncertainty.py", "tests/fits/test_propagation.py"],
    "imucal/fits/accelerometer.py": [
        "tests/fits/test_accelerometer.py",
        "tests/fits/test_std_exact.py",
        "tests/ingest/test_clipping_margins.py",
    ],
    "imucal/fits/alignment.py": ["tests/fits/test_alignment.py", "tests/fits/test_propagation.py"],
    "imucal/fits/ferraris.py": ["tests/fits/test_std_exact.py", "tests/fits/test_ferraris.py"],
    "imucal/fits/gyroscope.py": ["tests/fits/test_std_exact.py", "tests/fits/test_gyroscope.py"],
    "imucal/fits/magnetometer.py": ["tests/fits/test_magnetometer.py"],
    "imucal/fits/orientations.py": ["tests/pipeline/test_static_poses.py"],
    "imucal/fits/posetopose.py": ["tests/fits/test_std_exact.py", "tests/fits/test_posetopose.py"],
    "imucal/fits/propagation.py": ["tests/fits/test_propagation.py"],
    "imucal/fits/ratetable.py": ["tests/fits/test_std_exact.py", "tests/fits/test_gyroscope.py"],
    "imucal/fits/reference.py": ["tests/fits/test_std_exact.py", "tests/fits/test_reference.py"],
    "imucal/fits/wander.py": ["tests/fits/test_wander.py"],
    "imucal/validation/*.py": ["tests/validation"],
    "imucal/noise/*.py": ["tests/noise"],
    "imucal/segments/*.py": ["tests/segments"],
    "imucal/ingest/checks.py": [
        "tests/ingest/test_clipping_margins.py",
        "tests/ingest/test_streaming.py",
        "tests/ingest/test_ingest_errors.py",
        "tests/ingest/test_repeated_times.py",
    ],
    "imucal/terms/selection.py": [
        "tests/terms/test_terms.py::test_decide_follows_the_switch_and_the_diagnosis",
        "tests/terms/test_terms.py::test_settings_defaults_are_the_schemas",
        "tests/terms/test_settings_errors.py",
    ],
    "imucal/terms/heldout.py": ["tests/terms/test_order_rules.py", "tests/terms/test_terms.py"],
    "imucal/terms/blockspread.py": [
        "tests/terms/test_order_rules.py",
        "tests/terms/test_poseholdout.py",
    ],
    "imucal/terms/poseholdout.py": [
        "tests/terms/test_order_rules.py",
        "tests/terms/test_poseholdout.py",
    ],
    # the sim-to-real gap: each module's own tests, those of a few minutes left out (the
    # estimators' recovery, the whole-session sweeps of tests/gap/test_gap.py and the
    # disturbance sessions); its figures are pictures, not mutated
    "imucal/gap/attribution.py": ["tests/gap/test_decision_rules.py"],
    "imucal/gap/blind.py": ["tests/gap/test_gap_blind.py", "tests/gap/test_gap_detection.py"],
    "imucal/gap/blocks.py": ["tests/gap/test_gap_blocks.py"],
    "imucal/gap/catalogue.py": ["tests/gap/test_catalogue.py", "tests/gap/test_new_effect.py"],
    "imucal/gap/checks.py": ["tests/gap/test_gap_blind.py", "tests/gap/test_gap_stress.py"],
    "imucal/gap/clipping.py": ["tests/gap/test_gap_clipping.py"],
    "imucal/gap/composite.py": [
        "tests/gap/test_gap_static.py",
        "tests/gap/test_gap_rests.py",
        "tests/gap/test_gap_motion.py",
    ],
    "imucal/gap/detection.py": ["tests/gap/test_gap_detection.py"],
    "imucal/gap/diagnosis.py": ["tests/gap/test_outside.py"],
    "imucal/gap/disturbance.py": DISTURBANCE_UNITS,
    "imucal/gap/effects.py": ["tests/gap/test_gates.py", "tests/gap/test_gap_blocks.py"],
    "imucal/gap/fieldfit.py": ["tests/gap/test_gap_rests.py"],
    "imucal/gap/locations.py": ["tests/gap/test_gap_blocks.py"],
    "imucal/gap/misalignment.py": ["tests/gap/test_gap_blocks.py", "tests/gap/test_gates.py"],
    "imucal/gap/motion.py": ["tests/gap/test_gap_motion.py"],
    "imucal/gap/motionstats.py": ["tests/gap/test_gap_motion.py"],
    "imucal/gap/motiontwin.py": ["tests/gap/test_gap_motion.py"],
    "imucal/gap/null.py": ["tests/gap/test_decision_rules.py"],
    "imucal/gap/outside.py": ["tests/gap/test_outside.py"],
    "imucal/gap/poses.py": ["tests/gap/test_gap_poses.py"],
    "imucal/gap/rests.py": ["tests/gap/test_gap_rests.py"],
    "imucal/gap/scoring.py": ["tests/gap/test_outside.py", "tests/gap/test_gap_blocks.py"],
    "imucal/gap/session.py": ["tests/gap/test_gap_blocks.py"],
    "imucal/gap/static.py": ["tests/gap/test_gap_static.py"],
    "imucal/gap/statictwin.py": ["tests/gap/test_gap_static.py", "tests/gap/test_gap_rests.py"],
    "imucal/gap/statistics.py": ["tests/gap/test_gap_blocks.py"],
    "imucal/gap/streams.py": ["tests/gap/test_gap_static.py"],
    "imucal/gap/stress.py": ["tests/gap/test_gap_stress.py"],
    "imucal/gap/temperature.py": [
        "tests/gap/test_decision_rules.py",
        "tests/gap/test_gap_poses.py",
    ],
    "imucal/gap/twin.py": ["tests/gap/test_gap_blocks.py", "tests/gap/test_gates.py"],
    "imucal/gap/wandershape.py": ["tests/gap/test_wandershape.py"],
    "imucal/gap/worldfield.py": DISTURBANCE_UNITS,
    "imucal/gap/library/*.py": [
        "tests/gap/test_gates.py",
        "tests/gap/test_catalogue.py",
        "tests/gap/test_wandershape.py",
    ],
    "imucal/pipeline/*.py": ["tests/pipeline"],
    "imucal/pipeline/*/*.py": ["tests/pipeline"],
}
EQUIVALENT = Path(__file__).resolve().parent / "equivalent.txt"


def targets(path: str) -> list[str] | None:
    for pattern, tests in TARGETS.items():
        if fnmatch.fnmatch(path, pattern) and path.count("/") == pattern.count("/"):
            return tests
    return None


def modules(selected: list[str] | None) -> list[str]:
    found = subprocess.run(
        ["git", "ls-files", "imucal"], cwd=REPO, capture_output=True, text=True, check=True
    ).stdout.split()
    out = [p for p in found if p.endswith(".py") and targets(p) is not None]
    out = [p for p in out if not p.endswith("__init__.py")]
    return [p for p in out if not selected or p in selected]


def changed_lines(base: str) -> dict[str, set[int]]:
    """Lines changed since ``base`` per module (the new side of ``git diff -U0``)."""
    diff = subprocess.run(
        ["git", "diff", "-U0", base, "--", "imucal"],
        cwd=REPO,
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    out: dict[str, set[int]] = defaultdict(set)
    path = None
    for line in diff.splitlines():
        if line.startswith("+++ "):
            path = line[6:] if line.startswith("+++ b/") else None
        elif line.startswith("@@") and path:
            m = re.search(r"\+(\d+)(?:,(\d+))?", line)
            start, count = int(m.group(1)), int(m.group(2) or 1)
            out[path] |= set(range(start, start + max(count, 1)))
    return out


def changed_functions(source: str, lines: set[int]) -> list[tuple[int, int]]:
    """Line spans of the innermost functions holding a changed line (a changed line outside
    any function: the whole module)."""
    tree = ast.parse(source)
    spans = [
        (n.lineno, n.end_lineno)
        for n in ast.walk(tree)
        if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))
    ]
    out = set()
    for line in lines:
        holding = [s for s in spans if s[0] <= line <= s[1]]
        out.add(min(holding, key=lambda s: s[1] - s[0]) if holding else (1, 10**9))
    return sorted(out)


def load_equivalent() -> dict[str, str]:
    out = {}
    if EQUIVALENT.is_file():
        for line in EQUIVALENT.read_text().splitlines():
            if line.strip() and not line.startswith("#"):
                name, _, why = line.partition(" ")
                out[name] = why.strip()
    return out


def scratch_copy(where: Path | None) -> Path:
    """The tracked files copied to ``where`` (default a new temporary folder), with the
    shared folder beside it as beside the checkout (tests that read it skip without it)."""
    where = Path(tempfile.mkdtemp(prefix="imucal-mutation-")) / "repo" if where is None else where
    files = subprocess.run(
        ["git", "ls-files"], cwd=REPO, capture_output=True, text=True, check=True
    ).stdout.split()
    for f in files:
        src = REPO / f
        if src.is_file():
            dst = where / f
            dst.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dst)
    shared = REPO.parent / "shared"
    if shared.is_dir() and not (where.parent / "shared").exists():
        os.symlink(shared, where.parent / "shared")
    return where


def run_tests(root: Path, tests: list[str], timeout: float | None) -> tuple[str, float]:
    env = dict(
        os.environ,
        PYTHONPATH=str(root),
        OPENBLAS_NUM_THREADS="1",
        OMP_NUM_THREADS="1",
        PYTHONDONTWRITEBYTECODE="1",
    )
    cmd = [
        sys.executable,
        "-m",
        "pytest",
        "-x",
        "-q",
        "-p",
        "no:cacheprovider",
        "-m",
        "not slow",
        *tests,
    ]
    start = time.monotonic()
    try:
        done = subprocess.run(
            cmd, cwd=root, env=env, capture_output=True, text=True, timeout=timeout
        )
    except subprocess.TimeoutExpired:
        return "timeout", time.monotonic() - start
    seconds = time.monotonic() - start
    if done.returncode == 0:
        return "survived", seconds
    if done.returncode in (1, 2, 4):
        # a test failed, or the mutated module does not import (a collection error)
        return "killed", seconds
    return f"error {done.returncode}: {done.stdout[-300:]}{done.stderr[-300:]}", seconds


#: Mutants per module of a package whose tests are long (the pipeline's run whole chains).
PACKAGE_SAMPLE = {"imucal/pipeline": 2, "imucal/gap": 2}
#: A mutant whose tests run longer than this (s) is a timeout: it loops (the longest target,
#: tests/pipeline, takes about 4 minutes on an idle core).
TIMEOUT_S = 900.0


def package_of(path: str) -> str:
    return "/".join(path.split("/")[:2]) if path.count("/") > 1 else path


def sample(args) -> list[Mutant]:
    """The mutants of the run: a fixed random sample per module, or those of the changed
    functions."""
    chosen: list[Mutant] = []
    wanted = changed_lines(args.base) if args.base else None
    for path in modules(args.module):
        source = (REPO / path).read_text()
        found = mutants(path, source)
        if wanted is not None:
            if path not in wanted:
                continue
            spans = changed_functions(source, wanted[path])
            found = [m for m in found if any(a <= m.line <= b for a, b in spans)]
        elif args.sample:
            k = min(PACKAGE_SAMPLE.get(package_of(path), args.sample), args.sample, len(found))
            found = random.Random(f"{args.seed}:{path}").sample(found, k)
        chosen += sorted(found, key=lambda m: (m.line, m.col, m.kind))
    # round robin over the modules: a run stopped early has sampled every module alike
    # (the modules in a fixed random order within a round: a run stopped in a round has not
    # favoured the first modules by name)
    paths = sorted({m.path for m in chosen})
    random.Random(args.seed).shuffle(paths)
    place = {p: i for i, p in enumerate(paths)}
    rank = Counter()
    order = []
    for m in chosen:
        order.append((rank[m.path], place[m.path], m.line, m.col, m.kind))
        rank[m.path] += 1
    return [m for _, m in sorted(zip(order, chosen), key=lambda pair: pair[0])]


def run_one(root: Path, m: Mutant) -> tuple[str, float]:
    """The mutant's status in the scratch copy ``root`` (the module restored after)."""
    target = root / m.path
    original = target.read_text()
    target.write_text(apply(original, m))
    try:
        return run_tests(root, targets(m.path), TIMEOUT_S)
    finally:
        target.write_text(original)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sample", type=int, default=6, help="mutants per module (0: all)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--module", action="append", help="only these modules (repeatable)")
    parser.add_argument("--base", help="only mutants inside functions changed since this ref")
    parser.add_argument("--jobs", type=int, default=1, help="mutants run at once (one copy each)")
    parser.add_argument("--scratch", type=Path, help="scratch folder (default: a new temp one)")
    parser.add_argument("--out", type=Path, help="results (default: results.jsonl in the scratch)")
    parser.add_argument("--list", action="store_true", help="list the sample, run nothing")
    parser.add_argument(
        "--resume", type=Path, help="a results file: its mutants are not run again (appended to)"
    )
    parser.add_argument(
        "--check", action="store_true", help="first run each module's tests unmutated (must pass)"
    )
    args = parser.parse_args(argv)

    chosen = sample(args)
    if args.resume is not None and args.resume.is_file():
        done = {json.loads(line)["mutant"] for line in args.resume.read_text().splitlines()}
        chosen = [m for m in chosen if m.name not in done]
        args.out = args.out or args.resume
    if args.list:
        for m in chosen:
            print(m.name, repr(m.original), "->", repr(m.replacement))
        print(f"{len(chosen)} mutants")
        return 0
    base = args.scratch or Path(tempfile.mkdtemp(prefix="imucal-mutation-"))
    roots = [scratch_copy(base / f"copy{j}" / "repo") for j in range(args.jobs)]
    out_path = args.out or base / "results.jsonl"
    print(
        f"scratch copies under {base}; {len(chosen)} mutants, {args.jobs} at once; results in "
        f"{out_path}",
        flush=True,
    )
    if args.check:
        for tests in sorted({tuple(targets(m.path)) for m in chosen}):
            status, seconds = run_tests(roots[0], list(tests), TIMEOUT_S)
            if status != "survived":
                raise SystemExit(f"{' '.join(tests)} fail on the unmutated code: {status}")
            print(f"unmutated: {' '.join(tests)} pass ({seconds:.0f} s)", flush=True)
    equivalent = load_equivalent()
    counts: dict[str, Counter] = defaultdict(Counter)
    free = queue.Queue()
    for root in roots:
        free.put(root)

    def work(m: Mutant) -> tuple[Mutant, str, float]:
        root = free.get()
        try:
            return (m, *run_one(root, m))
        finally:
            free.put(root)

    with out_path.open("a") as out, ThreadPoolExecutor(args.jobs) as pool:
        for m, status, seconds in pool.map(work, chosen):
            if status == "survived" and m.name in equivalent:
                status = "equivalent"
            counts[package_of(m.path)][status.split(":")[0]] += 1
            record = {
                "mutant": m.name,
                "original": m.original,
                "replacement": m.replacement,
                "status": status,
                "seconds": round(seconds, 1),
            }
            out.write(json.dumps(record) + "\n")
            out.flush()
            print(
                f"{status:10s} {seconds:6.1f}s {m.name} {m.original!r} -> {m.replacement!r}",
                flush=True,
            )
    print(summary(counts))
    return 0


def summary(counts: dict[str, Counter]) -> str:
    """The score per package as a markdown table: killed and timeouts over the mutants that
    are not known equivalent."""
    rows = [
        "| package | mutants | killed | timeout | equivalent | survived | score |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    for package, c in sorted(counts.items()):
        detected = c["killed"] + c["timeout"]
        scored = sum(c.values()) - c["equivalent"]
        score = f"{100 * detected / scored:.0f} %" if scored else "-"
        rows.append(
            f"| `{package}` | {sum(c.values())} | {c['killed']} | {c['timeout']} | "
            f"{c['equivalent']} | {c['survived']} | {score} |"
        )
    return "\n".join(rows)


if __name__ == "__main__":
    raise SystemExit(main())
