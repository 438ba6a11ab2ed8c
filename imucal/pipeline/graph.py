"""The paper's calibration stages as one executable graph: what each reads, when it applies,
the settings it takes, how it runs and what it writes.

Every stage of the full protocol is a :class:`Node`, defined once here. The workflow runs a
sensor's nodes of :data:`FULL_PROTOCOL` in one rule (:mod:`imucal.pipeline.jobs`,
``workflow/rules/stages.smk``, one script ``workflow/scripts/stage.py``), each node writing its
own artifact, so every stage's result stays a file and a sensor's stages can be rerun alone on
new data. The in-process chain (:func:`imucal.pipeline.full.calibrate_session`, which the
diagnosis's twin, the closed loop and the checks use) runs the same nodes in the same order with
:func:`run_nodes`, with the same settings (:meth:`Node.settings_of`) and the same outcome when a
stage cannot run on the data (a not-run record, :mod:`imucal.pipeline.outcome`). The two paths
therefore agree by construction. The partial path's stages are nodes too
(:data:`imucal.pipeline.partial.driver.PARTIAL_PROTOCOL`), run by the same runner
(:func:`run_graph`) with the review of each final fit.

What a node reads is named by *source*:

* ``rotation3d``, ``cube``, ``static``, ``ratetable``: an ingested recording (table);
* ``lowpass``: the low-pass filtered rotation3d (table);
* ``segments``: the segments table;
* ``truth``: the dataset's ``truth.json`` where it has one (the workflow only);
* another node's name: that node's artifact (dict);
* ``session``: the partial path's session (its recordings, segments and references), from
  which its stages choose what they fit.
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from imucal.pipeline import stages
from imucal.pipeline.options import PipelineOptions
from imucal.pipeline.outcome import NotApplicable, StageNotRun, not_run_reason, not_run_record

#: Sources that are tables read from parquet (the others are JSON artifacts).
TABLE_SOURCES = ("rotation3d", "cube", "static", "ratetable", "lowpass", "segments")

#: The settings a node may take, each read from the pipeline's options in one place.
SETTINGS: dict[str, Callable[[PipelineOptions], Any]] = {
    "field_norm": lambda o: float(o.field_norm),
    "gravity_m_s2": lambda o: float(o.gravity_m_s2),
    "acc_limit_m_s2": lambda o: o.limit("acc"),
    "gyr_limit_rad_s": lambda o: o.limit("gyr"),
    "exact": lambda o: bool(o.exact_rotation),
    "with_covariance": lambda o: bool(o.with_covariance),
    "mag_refine_lm": lambda o: bool(o.methods.mag_refine_lm),
    "mag_alignment": lambda o: o.methods.mag_alignment,
    "acc_cube": lambda o: o.methods.acc_cube,
    "acc_alignment": lambda o: o.methods.acc_alignment,
    "gyr_bias_estimator": lambda o: o.methods.gyr_bias_estimator,
    "gyr_alignment": lambda o: o.methods.gyr_alignment,
}


@dataclass(frozen=True)
class Output:
    """A file a node writes besides its JSON artifact: a figure or the paper's tables.

    Attributes
    ----------
    key : str
        Its name among the node's outputs (the key the node's run returns it under).
    path : str
        File under ``results/{dataset}/``.
    caption : str
        Its caption's reStructuredText file, relative to the repository's root.
    category : str
        The sensor's section of Snakemake's report.
    """

    key: str
    path: str
    caption: str
    category: str


def _figure(key: str, category: str) -> Output:
    return Output(key, f"figures/{key}.png", f"imucal/report/captions/{key}.rst", category)


@dataclass(frozen=True)
class Node:
    """One stage of the paper's chain.

    Attributes
    ----------
    name : str
        The stage's (and its rule's) name.
    artifact : str
        Its JSON artifact under ``results/{dataset}/``.
    reads : callable
        ``reads(recordings) -> {argument: source}`` for a session with the given ingested
        recordings (the sources are listed in the module docstring).
    run : callable
        ``run(inputs, settings, draw) -> (artifact, outputs)``: ``inputs`` maps each argument
        to its table or artifact; a not-run artifact is passed as its record only for the
        arguments in ``tolerates`` (the others stop the node with its reason); ``outputs``
        maps :attr:`outputs` keys to figures or tables, empty unless ``draw``.
    settings : tuple of str
        The :data:`SETTINGS` it takes (a changed one reruns its rule).
    outputs : tuple of Output
        Figures and tables it writes besides the artifact.
    needs : str or None
        A recording without which the stage does not apply to a session.
    tolerates : tuple of str
        Arguments that may be missing or not run (the run decides what it does without them).
    readings : tuple of str
        The sensors whose readings it reads from the recordings ('acc', 'gyr', 'mag'); its
        result depends on the others' only through the artifacts it reads.
    """

    name: str
    artifact: str
    reads: Callable[[frozenset], dict]
    run: Callable[[Mapping, Mapping, bool], tuple]
    settings: tuple = ()
    outputs: tuple = ()
    needs: str | None = None
    tolerates: tuple = ()
    readings: tuple = ()

    def applies(self, recordings: frozenset) -> bool:
        """The stage runs on a session with these ingested recordings."""
        return self.needs is None or self.needs in recordings

    def settings_of(self, options: PipelineOptions) -> dict:
        """Its settings from the pipeline's options, plain values (a rule's ``params``)."""
        return {key: SETTINGS[key](options) for key in self.settings}


def _alignment(s: Mapping, method: str) -> dict:
    """The keywords of an alignment stage (eqs. 25-31): its method, the exact rotation or the
    small-angle form, and whether its covariance is carried."""
    return {"method": s[method], "exact": s["exact"], "with_covariance": s["with_covariance"]}


def _mag_step1(i: Mapping, s: Mapping, draw: bool) -> tuple:
    return stages.fit_mag_step1(i, field_norm=s["field_norm"], refine_lm=s["mag_refine_lm"]), {}


def _mag_step2(i: Mapping, s: Mapping, draw: bool) -> tuple:
    mag = stages.align_mag(
        i["rotation3d"], i["segments"], i["mag_step1"], **_alignment(s, "mag_alignment")
    )
    if not draw:
        return mag, {}
    from imucal.plots.magnetometer import plot_magnetometer_steps

    return mag, plot_magnetometer_steps(i["rotation3d"], i["segments"], mag)


def _recordings(i: Mapping) -> dict:
    """The recordings among a node's inputs (a stage that chooses its own from them)."""
    return {k: v for k, v in i.items() if k != "segments"}


def _acc_cube(i: Mapping, s: Mapping, draw: bool) -> tuple:
    return stages.fit_acc_cube(
        _recordings(i),
        i["segments"],
        gravity_m_s2=s["gravity_m_s2"],
        saturation_limit_m_s2=s["acc_limit_m_s2"],
        method=s["acc_cube"],
        figures=draw,
    )


def _acc_align(i: Mapping, s: Mapping, draw: bool) -> tuple:
    acc = stages.align_acc(
        i["lowpass"], i["segments"], i["acc_cube"], **_alignment(s, "acc_alignment")
    )
    return acc, {}


def _gyr_bias(i: Mapping, s: Mapping, draw: bool) -> tuple:
    return stages.estimate_gyr_bias(_recordings(i), i["segments"], figures=draw)


def _gyr_align(i: Mapping, s: Mapping, draw: bool) -> tuple:
    bias, _ = stages.gyr_bias_value(i["gyr_bias"], s["gyr_bias_estimator"])
    return stages.align_gyr(i["lowpass"], i["segments"], bias, **_alignment(s, "gyr_alignment")), {}


def _gyr_scale(i: Mapping, s: Mapping, draw: bool) -> tuple:
    # the phase angles need one calibrated sensor of the two
    acc, mag = usable(i.get("acc_align")), usable(i.get("mag_step2"))
    if acc is None and mag is None:
        why = [not_run_reason(i[k]) for k in ("acc_align", "mag_step2") if k in i]
        raise NotApplicable(
            "needs a calibrated magnetometer (mag_step2) or accelerometer (acc_align) to "
            "measure the phase angles" + "".join(f"; {w}" for w in why if w)
        )
    scale = stages.estimate_gyr_scale(
        i["rotation3d"],
        i["lowpass"],
        i["segments"],
        i["gyr_bias"],
        i["gyr_align"],
        acc,
        mag,
        bias_estimator=s["gyr_bias_estimator"],
        with_covariance=s["with_covariance"],
    )
    return scale, {}


def _gyr_table(i: Mapping, s: Mapping, draw: bool) -> tuple:
    return stages.fit_gyr_table(
        i["ratetable"], i["segments"], saturation_limit_rad_s=s["gyr_limit_rad_s"], figures=draw
    )


def _gyr_table_align(i: Mapping, s: Mapping, draw: bool) -> tuple:
    table = i["gyr_table"]
    alignment = stages.align_gyr(
        i["lowpass"], i["segments"], table["bias"], table["upper"], **_alignment(s, "gyr_alignment")
    )
    return alignment, {}


def _gyr(i: Mapping, s: Mapping, draw: bool) -> tuple:
    # the rate table's stages may not have run (the tool-free result is used then); with them,
    # the tool-free scale (eq. 36) is not needed and may not have run
    table, table_alignment = usable(i.get("gyr_table")), usable(i.get("gyr_table_align"))
    with_table = table is not None and table_alignment is not None
    scale = usable(i["gyr_scale"]) if with_table else checked(i["gyr_scale"])
    gyr, tables = stages.combine_gyr(
        i["gyr_bias"],
        scale,
        table,
        table_alignment,
        bias_estimator=s["gyr_bias_estimator"],
        exact=s["exact"],
        truth=i.get("truth"),
        with_covariance=s["with_covariance"],
    )
    return gyr, {"tables": tables} if draw else {}


def _fixed(**sources: str) -> Callable[[frozenset], dict]:
    return lambda recordings: dict(sources)


def _mag_step1_reads(recordings: frozenset) -> dict:
    """rotation3d, and the cube's magnetometer samples offered for coverage."""
    return {r: r for r in ("rotation3d", "cube") if r in recordings}


def _gyr_bias_reads(recordings: frozenset) -> dict:
    """The static recording, or the recordings whose static pauses stand in for it."""
    names = ("static",) if "static" in recordings else ("rotation3d", "cube")
    return {r: r for r in names} | {"segments": "segments"}


def _gyr_reads(recordings: frozenset) -> dict:
    """Bias and tool-free scale, the rate table's stages with a rate table, and the truth."""
    table = ("gyr_table", "gyr_table_align") if "ratetable" in recordings else ()
    return {k: k for k in ("gyr_bias", "gyr_scale", *table, "truth")}


_ALIGNMENT = ("exact", "with_covariance")

#: The stages of the paper's protocol in run order (a sensor's run in one rule of the workflow).
FULL_PROTOCOL: dict[str, Node] = {
    node.name: node
    for node in (
        Node(
            "mag_step1",
            "mag_step1.json",
            _mag_step1_reads,
            _mag_step1,
            ("field_norm", "mag_refine_lm"),
            readings=("mag",),
        ),
        Node(
            "mag_step2",
            "mag.json",
            _fixed(rotation3d="rotation3d", segments="segments", mag_step1="mag_step1"),
            _mag_step2,
            ("mag_alignment", *_ALIGNMENT),
            tuple(
                _figure(k, "Magnetometer")
                for k in ("mag_raw", "mag_step1", "mag_phases", "mag_step2")
            ),
            readings=("mag",),
        ),
        Node(
            "acc_cube",
            "acc_cube.json",
            _fixed(cube="cube", segments="segments"),
            _acc_cube,
            ("gravity_m_s2", "acc_limit_m_s2", "acc_cube"),
            (_figure("acc_cube", "Accelerometer"),),
            readings=("acc",),
        ),
        Node(
            "acc_align",
            "acc.json",
            _fixed(lowpass="lowpass", segments="segments", acc_cube="acc_cube"),
            _acc_align,
            ("acc_alignment", *_ALIGNMENT),
            readings=("acc",),
        ),
        Node(
            "gyr_bias",
            "gyr_bias.json",
            _gyr_bias_reads,
            _gyr_bias,
            outputs=(_figure("gyr_bias", "Gyroscope"),),
            readings=("gyr",),
        ),
        Node(
            "gyr_align",
            "gyr_align.json",
            _fixed(lowpass="lowpass", segments="segments", gyr_bias="gyr_bias"),
            _gyr_align,
            ("gyr_bias_estimator", "gyr_alignment", *_ALIGNMENT),
            readings=("gyr",),
        ),
        Node(
            "gyr_scale",
            "gyr_scale.json",
            _fixed(
                rotation3d="rotation3d",
                lowpass="lowpass",
                segments="segments",
                gyr_bias="gyr_bias",
                gyr_align="gyr_align",
                acc_align="acc_align",
                mag_step2="mag_step2",
            ),
            _gyr_scale,
            ("gyr_bias_estimator", "with_covariance"),
            tolerates=("acc_align", "mag_step2"),
            readings=("acc", "gyr", "mag"),
        ),
        Node(
            "gyr_table",
            "gyr_table.json",
            _fixed(ratetable="ratetable", segments="segments"),
            _gyr_table,
            ("gyr_limit_rad_s",),
            (_figure("gyr_table", "Gyroscope"),),
            needs="ratetable",
            readings=("gyr",),
        ),
        Node(
            "gyr_table_align",
            "gyr_table_align.json",
            _fixed(lowpass="lowpass", segments="segments", gyr_table="gyr_table"),
            _gyr_table_align,
            ("gyr_alignment", *_ALIGNMENT),
            needs="ratetable",
            readings=("gyr",),
        ),
        Node(
            "gyr",
            "gyr.json",
            _gyr_reads,
            _gyr,
            ("gyr_bias_estimator", *_ALIGNMENT),
            (Output("tables", "tables.csv", "workflow/report/tables.rst", "Gyroscope"),),
            tolerates=("gyr_scale", "gyr_table", "gyr_table_align", "truth"),
        ),
    )
}


def source_file(source: str) -> str | None:
    """The file a source is read from in the workflow, under ``results/{dataset}/`` (None for
    ``truth``, which is the dataset's own file)."""
    if source == "truth":
        return None
    if source == "lowpass":
        return "lowpass/rotation3d.parquet"
    if source == "segments":
        return "segments.parquet"
    if source in TABLE_SOURCES:
        return f"ingest/{source}.parquet"
    return FULL_PROTOCOL[source].artifact


def read_source(source: str, path: str | Path) -> Any:
    """A source read from its file: a table (parquet) or an artifact (JSON, not-run records
    kept as they are)."""
    from imucal.io import read_json, read_recording, read_segments

    if source == "segments":
        return read_segments(path)
    if source in TABLE_SOURCES:
        return read_recording(path)[0]
    return read_json(path)


def write_output(value: Any, path: str | Path) -> None:
    """A node's figure (PNG) or table (CSV) at ``path``."""
    if hasattr(value, "savefig"):
        from imucal.plots.figurefile import save_figure

        save_figure(value, path)
    else:
        value.to_csv(path, index=False)


def checked(artifact: Mapping) -> Mapping:
    """``artifact`` itself; raises :class:`StageNotRun` (with its reason) for a not-run record."""
    reason = not_run_reason(artifact)
    if reason:
        raise StageNotRun(reason)
    return artifact


def usable(artifact: Mapping | None) -> Mapping | None:
    """``artifact``, or None when it is missing or a not-run record."""
    return None if artifact is None or not_run_reason(artifact) else artifact


def node_inputs(node: Node, store: Mapping, recordings: frozenset) -> dict:
    """A node's inputs from what the chain holds (sources by name); a not-run artifact stops it
    unless it is an argument the node tolerates, and a tolerated missing source is left out."""
    inputs = {}
    for argument, source in node.reads(recordings).items():
        if source not in store:
            if argument in node.tolerates:
                continue
            raise KeyError(f"stage {node.name} reads {source!r}, which the chain does not hold")
        value = store[source]
        inputs[argument] = value if argument in node.tolerates else _checked_input(value)
    return inputs


def _checked_input(value: Any) -> Any:
    return checked(value) if isinstance(value, Mapping) else value


def unaffected(
    records: Mapping[str, Mapping],
    changed: Collection[str],
    recordings: frozenset,
    *,
    nodes: Mapping[str, Node] = FULL_PROTOCOL,
) -> dict[str, Mapping]:
    """The records of a session's stages that new readings of the ``changed`` sensors cannot
    move: stages that read none of them, directly or through an earlier stage.

    Parameters
    ----------
    records : dict of str to dict
        Stage name -> artifact or not-run record of the session before the change.
    changed : collection of str
        Sensors whose readings changed ('acc', 'gyr', 'mag'); the others' are the same to the bit.
    recordings : frozenset of str
        The session's recordings.
    nodes : dict of str to Node

    Returns
    -------
    dict
        The subset of ``records`` to hand to the runner as done.
    """
    kept: dict[str, Mapping] = {}
    for node in nodes.values():
        sources = set(node.reads(recordings).values()) & set(nodes)
        moved = set(node.readings) & set(changed) or sources - set(kept)
        if node.name in records and not moved:
            kept[node.name] = records[node.name]
    return kept


def run_graph(
    store: Mapping[str, Any],
    settings_for: Callable[[Node], Mapping],
    nodes: Mapping[str, Node],
    *,
    review: Callable[[str, dict, Mapping], dict] | None = None,
    reason: Callable[[Exception], str] = str,
) -> dict[str, Any]:
    """Run the nodes in order in process, without figures: the one runner of every chain.

    Each node that applies to the session is run on its inputs from ``store``; its artifact, or
    its not-run record when the data do not allow it (its fit or its conditions raise
    ``ValueError``, or a stage it needs did not run), joins the store under its name for the
    nodes after it.

    Parameters
    ----------
    store : dict
        The sources the chain starts from (recordings, derived tables, artifacts of stages
        already run, and any other source the nodes read).
    settings_for : callable
        ``settings_for(node)``: the node's settings (its :attr:`Node.settings` keys).
    nodes : dict of str to Node
        The graph, in run order.
    review : callable, optional
        ``review(name, artifact, store) -> artifact``: checks a node's artifact before it is
        kept (it may add warnings); a ``ValueError`` it raises makes the stage not run with
        its message (a fit not shipped).
    reason : callable
        The not-run reason of the exception that stopped a node (default its message).

    Returns
    -------
    dict
        ``store`` with each node's artifact or not-run record under its name; a node that does
        not apply to the session has no entry.
    """
    store = dict(store)
    # the recordings, not the derived tables nor the artifacts of stages already run
    derived = {"lowpass", "segments", *FULL_PROTOCOL, *nodes}
    recordings = frozenset(k for k in store if k not in derived)
    for node in nodes.values():
        if not node.applies(recordings):
            continue
        try:
            inputs = node_inputs(node, store, recordings)
            artifact, _ = node.run(inputs, settings_for(node), False)
            store[node.name] = review(node.name, artifact, store) if review else artifact
        except (ValueError, StageNotRun) as err:
            store[node.name] = not_run_record(node.name, reason(err))
    return store


def run_nodes(
    store: Mapping[str, Any],
    options: PipelineOptions,
    *,
    nodes: Mapping[str, Node] = FULL_PROTOCOL,
) -> dict[str, Any]:
    """Run the paper's stages in process as the workflow's rules run them
    (:func:`run_graph` with each node's settings from ``options``).

    Parameters
    ----------
    store : dict
        The sources the chain starts from: the ingested recordings (SI units), ``lowpass``
        and ``segments``.
    options : PipelineOptions
    nodes : dict of str to Node
        The graph (default the paper's protocol).

    Returns
    -------
    dict
        ``store`` with each node's artifact under its name: the fit's dict, or its not-run
        record when the data do not allow the stage (as :func:`~imucal.pipeline.outcome.
        stage_guard` writes it). A node that does not apply to the session has no entry.
    """
    return run_graph(store, lambda node: node.settings_of(options), nodes)
