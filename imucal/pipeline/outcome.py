"""Stages that cannot run on a session's data: their record, and the guard rule scripts run in.

A calibration stage can fail on the physics of a session rather than on its files: too few
static positions, magnetometer samples that do not describe an ellipsoid, phases clipped at the
gyroscope range. The fits then raise ``ValueError`` with a message in the data's terms. In the
workflow such a stage still ends: :func:`stage_guard` writes each of its outputs as a *not-run
record* (JSON ``{"not_run": {"stage", "reason"}}``, a figure that states the reason, the header
of the paper's tables) and every stage that reads it with :func:`read_artifact` does the same,
with the reason traced back. So a session that ingests always ends in a report that says what
ran and why the rest did not (``stages.json``). Errors that are not about the data (a missing
or malformed file, a bug) are not caught: they still stop the run with their message.
"""

from __future__ import annotations

import logging
import textwrap
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path

from imucal.io import read_json, write_json

logger = logging.getLogger(__name__)

#: Key of a not-run record.
NOT_RUN = "not_run"
#: Start of the reason of a stage that was fitted but whose result is not shipped (outside its
#: sensor's physical bounds, :mod:`imucal.validation.plausibility`); the report lists it among
#: its warnings.
NOT_SHIPPED = "fitted but not shipped"
#: Columns of the only CSV a stage writes (the paper's Tables I and II, ``tables.csv``).
TABLE_COLUMNS = ("table", "row", "x", "y", "z")


class NotApplicable(ValueError):
    """A stage's requirements are not met by the session's data (the message says which): no
    recording it fits on, too few poses, directions not covered. The workflow writes the
    stage's not-run record; the partial path lists it as not applicable."""


class NotShipped(ValueError):
    """A stage's fit ran but its calibration is refused (its message starts with
    :data:`NOT_SHIPPED` and says why): the sensor's next, simpler stage is shipped."""


class StageNotRun(Exception):
    """A stage cannot run because a stage it needs did not (the message says which and why)."""


def not_run_record(stage: str, reason: str) -> dict:
    """The JSON artifact of a stage that did not run."""
    return {NOT_RUN: {"stage": stage, "reason": reason}}


def not_run_reason(artifact: Mapping) -> str | None:
    """``"STAGE did not run: REASON"`` for a not-run record, else None."""
    record = artifact.get(NOT_RUN) if isinstance(artifact, Mapping) else None
    return f"{record['stage']} did not run: {record['reason']}" if record else None


def read_artifact(path: str | Path) -> dict:
    """A stage's JSON artifact.

    Raises
    ------
    StageNotRun
        If the artifact is a not-run record (the message names the stage and its reason).
    """
    artifact = read_json(path)
    reason = not_run_reason(artifact)
    if reason:
        raise StageNotRun(reason)
    return artifact


def read_optional_artifact(path: str | Path) -> dict | None:
    """A stage's JSON artifact, or None when the stage did not run."""
    artifact = read_json(path)
    return None if not_run_reason(artifact) else artifact


def _not_run_figure(stage: str, reason: str, path: Path) -> None:
    from matplotlib.figure import Figure

    from imucal.plots.figurefile import save_figure

    fig = Figure(figsize=(8, 2.2))
    fig.text(0.02, 0.85, f"{stage} did not run", fontsize=12, weight="bold", va="top")
    text = textwrap.fill(reason, width=100, max_lines=6, placeholder=" ...")
    fig.text(0.02, 0.65, text, fontsize=8, va="top", family="monospace")
    save_figure(fig, path)


def write_not_run(stage: str, reason: str, outputs: Mapping[str, str | Path]) -> None:
    """Write every output of a stage as its not-run form (JSON, PNG figure, CSV header)."""
    for path in map(Path, outputs.values()):
        path.parent.mkdir(parents=True, exist_ok=True)
        if path.suffix in (".json", ".yaml"):  # a JSON object is a YAML mapping too
            write_json(not_run_record(stage, reason), path)
        elif path.suffix == ".png":
            _not_run_figure(stage, reason, path)
        elif path.suffix == ".csv":
            path.write_text(",".join(TABLE_COLUMNS) + "\n")
        else:
            raise ValueError(f"{path}: no not-run form for a '{path.suffix}' output")


@contextmanager
def stage_guard(stage: str, outputs: Mapping[str, str | Path]) -> Iterator[None]:
    """Run a stage's body; when the data do not allow it, write its not-run outputs instead.

    Parameters
    ----------
    stage : str
        The stage's name (the rule's).
    outputs : mapping of str to path
        The rule's outputs (``snakemake.output``), all rewritten when the stage does not run,
        so that no partial result is left behind.
    """
    try:
        yield
    except (ValueError, StageNotRun) as err:
        reason = str(err)
        logger.warning("%s did not run: %s", stage, reason)
        write_not_run(stage, reason, dict(outputs.items()))
