"""The paper's stages as workflow jobs: a sensor's stages that need the same recording run in one
job, in run order, and each still writes its own artifact, figures and not-run record.

A job is one process: its recordings and the artifacts of earlier jobs are read once, and every
stage after the first reads its predecessors' artifacts as the next job would read them (written,
then read back from their files), so a stage's result does not depend on which job ran it. The
jobs of :data:`STAGE_JOBS` are the rules of ``workflow/rules/stages.smk``, all run by
``workflow/scripts/stage.py`` with :func:`run_job`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from imucal.constants import RECORDING_NAMES
from imucal.pipeline.graph import FULL_PROTOCOL, Node, node_inputs, read_source, write_output
from imucal.pipeline.outcome import stage_guard


@dataclass(frozen=True)
class StageJob:
    """Stages run together in one job.

    Attributes
    ----------
    name : str
        The job's (and its rule's) name, ``{sensor}_stages`` or ``{sensor}_{needs}_stages``.
    nodes : tuple of Node
        Its stages in run order (:data:`imucal.pipeline.graph.FULL_PROTOCOL`).
    """

    name: str
    nodes: tuple[Node, ...]

    @property
    def needs(self) -> str | None:
        """The recording without which none of its stages applies (None: they always apply)."""
        return self.nodes[0].needs

    def applies(self, recordings: frozenset) -> bool:
        """The job runs on a session with these ingested recordings."""
        return self.needs is None or self.needs in recordings

    def reads(self, recordings: frozenset) -> list[str]:
        """The sources its stages read from outside the job, in order of first use."""
        inside = {node.name for node in self.nodes}
        sources = [s for node in self.nodes for s in node.reads(recordings).values()]
        return list(dict.fromkeys(s for s in sources if s not in inside))

    def files(self) -> dict[str, tuple[str, str, str]]:
        """Its output files: key -> (stage, the stage's output key or 'artifact', path under
        ``results/{dataset}/``); a stage's artifact under the stage's name, each figure or table
        under ``{stage}_{key}``."""
        files = {}
        for node in self.nodes:
            files[node.name] = (node.name, "artifact", node.artifact)
            for out in node.outputs:
                files[f"{node.name}_{out.key}"] = (node.name, out.key, out.path)
        return files


def _sensor(node: Node) -> str:
    """The sensor a stage calibrates: the first word of its name (mag, acc, gyr)."""
    return node.name.split("_")[0]


def stage_jobs(nodes: Mapping[str, Node] = FULL_PROTOCOL) -> dict[str, StageJob]:
    """The stages grouped into jobs by sensor and needed recording, in run order.

    Raises
    ------
    ValueError
        If a job's stages would not run in the graph's order (a stage of another job between
        two of its stages reads one and is read by the other) or two output keys coincide.
    """
    grouped: dict[str, list[Node]] = {}
    for node in nodes.values():
        words = [_sensor(node), node.needs, "stages"]
        grouped.setdefault("_".join(w for w in words if w), []).append(node)
    jobs = {name: StageJob(name, tuple(members)) for name, members in grouped.items()}
    everything = frozenset(RECORDING_NAMES)
    for job in jobs.values():
        keys = [key for node in job.nodes for key in (node.name, *(o.key for o in node.outputs))]
        if len(job.files()) != len(keys):
            raise ValueError(f"job {job.name}: two of its output keys coincide")
        for other in jobs.values():
            if other is not job and {n.name for n in other.nodes} & set(job.reads(everything)):
                if {n.name for n in job.nodes} & set(other.reads(everything)):
                    raise ValueError(f"jobs {job.name} and {other.name} read each other")
    return jobs


#: The workflow's stage jobs, each one rule of ``workflow/rules/stages.smk``.
STAGE_JOBS: dict[str, StageJob] = stage_jobs()


def run_job(
    job: StageJob,
    sources: Mapping[str, str | Path],
    outputs: Mapping[str, str | Path],
    settings: Mapping[str, Mapping],
    recordings: frozenset,
) -> None:
    """Run a job's stages in order and write each one's files, or its not-run forms.

    Parameters
    ----------
    job : StageJob
        The job.
    sources : mapping of str to path
        The file of each source it reads from outside (:meth:`StageJob.reads`; ``truth`` only
        where the dataset has one).
    outputs : mapping of str to path
        The file of each key of :meth:`StageJob.files`.
    settings : mapping of str to mapping
        Each stage's settings (:meth:`imucal.pipeline.graph.Node.settings_of`), by stage.
    recordings : frozenset of str
        The session's ingested recordings.
    """
    from imucal.io import write_json

    store = {source: read_source(source, path) for source, path in sources.items()}
    files = job.files()
    for node in job.nodes:
        own = {kind: outputs[key] for key, (stage, kind, _) in files.items() if stage == node.name}
        with stage_guard(node.name, own):
            artifact, written = node.run(
                node_inputs(node, store, recordings), settings[node.name], True
            )
            write_json(artifact, own["artifact"])
            for key, value in written.items():
                write_output(value, own[key])
        store[node.name] = read_source(node.name, own["artifact"])
