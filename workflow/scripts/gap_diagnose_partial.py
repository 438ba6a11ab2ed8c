"""Rule gap_diagnose_partial: the gap diagnosis of a partial session (imucal.gap.composite)."""

import logging
from pathlib import Path
from typing import TYPE_CHECKING

from imucal.gap import DiagnosisSettings
from imucal.gap.clipping import ingest_clip_fractions, note_saturation
from imucal.gap.composite import diagnose_partial_session, diagnose_rests_scope, partial_scope
from imucal.gap.motion import reference_part
from imucal.gap.poses import diagnose_poses
from imucal.io import read_json, read_recording, read_segments, write_json
from imucal.io.dataset import read_dataset
from imucal.io.logs import log_to
from imucal.plots.figurefile import save_figure
from imucal.report.gapfigures import plot_effects, plot_gap_map

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

log_to(snakemake.log[0])
info = read_dataset(Path(snakemake.input.dataset_yaml).parent)
inputs = dict(snakemake.input.items())
scope = partial_scope(
    static="static" in info.recordings,
    references=bool(info.orientation_references),
    poses=snakemake.params.poses_recording is not None,
)
calibration = read_json(snakemake.input.calibration)
motion = not_scored = None
static = read_recording(inputs["static"])[0] if "static" in scope else None
if "reference" in scope:
    references = {}
    for path in snakemake.input.orientation:
        table, metadata = read_recording(path)
        references[metadata["recording"]] = (table, metadata)
    motion, not_scored = reference_part(
        tables={name: read_recording(inputs[f"moving_{name}"])[0] for name in references},
        references=references,
        calibration=calibration,
        segments=read_segments(snakemake.input.segments),
        where={name: info.reference_where(name) for name in references},
        sensitivity=info.sensitivity,
        gravity_m_s2=info.gravity_m_s2,
        windows_s=snakemake.params.windows_s,
    )
common = dict(
    dataset=snakemake.wildcards.dataset,
    calibration=calibration,
    sensitivity=info.sensitivity,
    gravity_m_s2=info.gravity_m_s2,
    settings=DiagnosisSettings.from_config(snakemake.params.settings),
)
if scope == "poses":  # static poses with a temperature channel, no static recording
    result = diagnose_poses(
        read_recording(inputs["poses"])[0], read_segments(snakemake.input.segments),
        recording=snakemake.params.poses_recording, settle_s=snakemake.params.settle_s, **common,
    )  # fmt: skip
elif scope == "rests":  # the longest rest as the static recording, else the short ones pooled
    tables = {k.removeprefix("rest_"): read_recording(p)[0]
              for k, p in inputs.items() if k.startswith("rest_")}  # fmt: skip
    result = diagnose_rests_scope(tables, read_segments(snakemake.input.segments), **common)
else:
    result = diagnose_partial_session(
        static, motion=motion, reference_not_scored=not_scored, **common
    )
# clipping is seen in the readings themselves, whatever the scope can replay
note_saturation(result, ingest_clip_fractions(read_json(snakemake.input.summary)))
write_json(result, snakemake.output.diagnosis)
save_figure(plot_gap_map(result), snakemake.output.gap_map)
save_figure(plot_effects(result), snakemake.output.effects)
logging.info("scope %s, explained %s", result["scope"], result["explained"])
