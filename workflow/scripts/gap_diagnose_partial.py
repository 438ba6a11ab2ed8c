"""Rule gap_diagnose_partial: the gap diagnosis of a partial session (imucal.gap.composite)."""

import logging
from pathlib import Path
from typing import TYPE_CHECKING

from imucal.gap import DiagnosisSettings
from imucal.gap.composite import diagnose_partial_session, rest_as_static
from imucal.gap.figures import plot_effects, plot_gap_map
from imucal.gap.motion import reference_part
from imucal.gap.poses import diagnose_poses
from imucal.io import read_json, read_recording, read_segments, write_json
from imucal.io.dataset import read_dataset

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

logging.basicConfig(filename=snakemake.log[0], filemode="w", level=logging.INFO)
info = read_dataset(Path(snakemake.input.dataset_yaml).parent)
inputs = dict(snakemake.input.items())
calibration = read_json(snakemake.input.calibration)
motion = not_scored = static_source = None
static = read_recording(inputs["static"])[0] if "static" in inputs else None
if "orientation" in inputs:
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
elif static is None and "poses" not in inputs:
    static, static_source = rest_as_static(
        {
            k.removeprefix("rest_"): read_recording(p)[0]
            for k, p in inputs.items()
            if k.startswith("rest_")
        },
        read_segments(snakemake.input.segments),
    )
common = dict(
    motion=motion,
    reference_not_scored=not_scored,
    dataset=snakemake.wildcards.dataset,
    calibration=calibration,
    sensitivity=info.sensitivity,
    gravity_m_s2=info.gravity_m_s2,
    settings=DiagnosisSettings.from_config(snakemake.params.settings),
)
if "poses" in inputs:  # static poses with a temperature channel, no static recording
    result = diagnose_poses(
        read_recording(inputs["poses"])[0], read_segments(snakemake.input.segments),
        recording=snakemake.params.poses_recording, settle_s=snakemake.params.settle_s, **common,
    )  # fmt: skip
else:
    result = diagnose_partial_session(static, static_source=static_source, **common)
write_json(result, snakemake.output.diagnosis)
plot_gap_map(result).savefig(snakemake.output.gap_map, dpi=110)
plot_effects(result).savefig(snakemake.output.effects, dpi=110)
logging.info("scope %s, explained %s", result["scope"], result["explained"])
