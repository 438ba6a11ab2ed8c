"""What a partial session's runners read: its tables, segments, options and references
(:class:`Session`, the same for every stage), the record of what happened to a stage
(:class:`Outcome`) and the refusal of a stage whose requirements the data do not meet
(:class:`NotApplicable`, :func:`need`). The artifacts of the stages before are no part of the
session: each runner gets those it reads as its node's inputs.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Iterable, Mapping
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from imucal.pipeline.graph import FULL_PROTOCOL, SETTINGS
from imucal.pipeline.options import PipelineOptions
from imucal.pipeline.outcome import NotApplicable
from imucal.pipeline.registry import STAGES, split_held_out
from imucal.pipeline.stages.common import sensors_of
from imucal.segments.table import rows_of

if TYPE_CHECKING:
    from imucal.io.dataset import Dataset


@dataclasses.dataclass
class Outcome:
    """What happened to one stage.

    Attributes
    ----------
    name : str
    status : {'run', 'skipped'}
    reason : str
        Why it was skipped, or what it used.
    artifact : dict or None
        The stage's JSON-ready result when it ran.
    """

    name: str
    status: str
    reason: str
    artifact: dict | None = None

    def summary(self) -> dict:
        return {
            "stage": self.name,
            "what": STAGES[self.name].what,
            "status": self.status,
            "reason": self.reason,
        }


def need(condition: bool, reason: str) -> None:
    """Raise :class:`NotApplicable` with ``reason`` unless ``condition`` holds."""
    if not condition:
        raise NotApplicable(reason)


class Session:
    """The ingested tables, segments, options and references of one partial session.

    Parameters
    ----------
    tables : mapping of str to DataFrame
        Ingested recordings by name (SI units; absent sensors have no columns).
    segments : DataFrame
        Segments table of the session (automatic or from a section list).
    options : PipelineOptions
        The settings of its fits, as the other chains take them
        (:func:`imucal.pipeline.partial.session_options`).
    notes : mapping of str to str, optional
        Segmentation notes per recording (why its protocol was not found); they join the
        reasons of the stages that needed it.
    references : mapping, optional
        Recording -> (ingested orientation reference, its metadata) for the stage
        ``gyr_reference`` (:mod:`imucal.pipeline.reference`).
    reference_where : mapping, optional
        Recording -> key path of its reference in dataset.yaml (error messages).
    """

    def __init__(
        self,
        tables: Mapping[str, pd.DataFrame],
        segments: pd.DataFrame,
        options: PipelineOptions,
        *,
        notes: Mapping[str, str] | None = None,
        references: Mapping[str, tuple[pd.DataFrame, Mapping]] | None = None,
        reference_where: Mapping[str, str] | None = None,
    ):
        self.recordings = dict(tables)
        self.options = options
        self.methods = options.methods
        self.exact = options.exact_rotation
        self.references = dict(references or {})
        # a held-out recording is validated on, never fitted on (registry.split_held_out)
        held = split_held_out(self.references)[1]
        self.tables = {k: v for k, v in tables.items() if k != "reference" and k not in held}
        self.held_out_tables = {k: tables[k] for k in held if k in tables}
        self.reference_where = dict(reference_where or {})
        self.segments = segments
        self.gravity_m_s2 = options.gravity_m_s2
        self.ratetable = options.ratetable
        self.saturation_rad_s = options.limit("gyr")
        self.sensors = {name: sensors_of(t) for name, t in self.tables.items()}
        self.notes = dict(notes or {})

    def on(self, tables: Mapping[str, pd.DataFrame], segments: pd.DataFrame) -> Session:
        """The same session's options, notes and references on other recordings (a part of
        its data)."""
        return Session(
            tables,
            segments,
            self.options,
            notes=self.notes,
            references=self.references,
            reference_where=self.reference_where,
        )

    @functools.cached_property
    def settings(self) -> dict:
        """The settings of the stages (:data:`imucal.pipeline.graph.SETTINGS`) from the
        session's options; a range that is not known is None (nothing is left out)."""
        return {key: setting(self.options) for key, setting in SETTINGS.items()}

    def run_node(self, name: str, **inputs) -> dict:
        """The artifact of a stage the full protocol shares, run as its node
        (:data:`imucal.pipeline.graph.FULL_PROTOCOL`) on ``inputs``."""
        node = FULL_PROTOCOL[name]
        return node.run(inputs, {k: self.settings[k] for k in node.settings}, False)[0]

    @functools.cached_property
    def rotation3d_lowpass(self) -> pd.DataFrame:
        """The low-pass filtered rotation3d recording (both alignment stages use it)."""
        from imucal.segments.filtering import lowpass_recording

        order, cutoff = self.options.lowpass_order, self.options.lowpass_cutoff_hz
        return lowpass_recording(self.tables["rotation3d"], order=order, cutoff_hz=cutoff)

    def with_sensor(self, recording: str, sensor: str) -> bool:
        return recording in self.tables and sensor in self.sensors[recording]

    def has_phases(self, recording: str = "rotation3d") -> bool:
        return recording in self.tables and not rows_of(self.segments, recording, "phase").empty

    def need_phases(self, sensor: str) -> None:
        """Raise NotApplicable unless rotation3d has phases and ``sensor`` samples."""
        if self.has_phases() and self.with_sensor("rotation3d", sensor):
            return
        why = f"needs rotation3d phases about x, y, z with {sensor} samples"
        if "rotation3d" in self.notes:
            why += f" ({self.notes['rotation3d']})"
        elif "rotation3d" not in self.tables:
            why += " (no rotation3d recording)"
        raise NotApplicable(why)

    def poses(self, recording: str) -> pd.DataFrame:
        return rows_of(self.segments, recording, "position", "static")


def axis_vector(up: str) -> np.ndarray:
    """'+x', '-z', 'x' ... -> unit vector in B."""
    sign = -1.0 if up.startswith("-") else 1.0
    axis = up.lstrip("+-")
    if axis not in ("x", "y", "z"):
        raise ValueError(f"up direction {up!r}: expected '+x', '-x', ..., '-z'")
    v = np.zeros(3)
    v["xyz".index(axis)] = sign
    return v


def session_options(
    dataset: Dataset, metadata: Iterable[Mapping], settings: Mapping
) -> PipelineOptions:
    """The options of a partial session, built as the other chains build theirs
    (:meth:`PipelineOptions.of_dataset`) with the ranges its recordings give.

    Parameters
    ----------
    dataset : Dataset
        The session's ``dataset.yaml``.
    metadata : iterable of mapping
        The ingested recordings' metadata (their sensors' ranges,
        :func:`imucal.ingest.sensor_limits`).
    settings : mapping
        The pipeline's settings (:func:`imucal.pipeline.options.pipeline_settings`).

    Returns
    -------
    PipelineOptions
        With ``ranges`` where every recording of a sensor reads it in raw counts with one
        range; readings at a range are clipped and left out of the fits where it is known.
    """
    from imucal.ingest import sensor_limits

    return PipelineOptions.of_dataset(
        dataset, **settings, ranges=sensor_limits(metadata, dataset.range_counts)
    )


def session_of(
    dataset: Dataset,
    ingested: Mapping[str, tuple[pd.DataFrame, Mapping]],
    segments: pd.DataFrame,
    notes: Mapping[str, str],
    references: Mapping[str, tuple[pd.DataFrame, Mapping]],
    settings: Mapping,
) -> Session:
    """A partial session as the workflow reads it.

    Parameters
    ----------
    dataset : Dataset
        The session's ``dataset.yaml``.
    ingested : mapping
        Recording -> (ingested table, its metadata), every recording but the reference.
    segments : DataFrame
        The session's segments table.
    notes : mapping of str to str
        The segmentation's notes (the segments' metadata ``notes``).
    references : mapping
        Recording -> (ingested orientation reference, its metadata).
    settings : mapping
        The pipeline's settings (:func:`imucal.pipeline.options.pipeline_settings`).

    Returns
    -------
    Session
    """
    return Session(
        {name: table for name, (table, _) in ingested.items()},
        segments,
        session_options(dataset, (meta for _, meta in ingested.values()), settings),
        notes=notes,
        references=references,
        reference_where={name: dataset.reference_where(name) for name in references},
    )
