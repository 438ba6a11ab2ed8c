"""The stages of the calibration, defined once: name, sensor and what each does.

The partial path (:mod:`imucal.pipeline.partial`) runs them in this order and ``stages.json``
lists them in this order; how the full protocol's stages run, and their artifacts, are the
nodes of :mod:`imucal.pipeline.graph`. Which of the two paths a dataset takes is decided here
too, from its ``dataset.yaml`` alone (:func:`is_full_protocol`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from imucal.columns import SENSORS


@dataclass(frozen=True)
class Stage:
    """One stage of the calibration.

    Attributes
    ----------
    name : str
        Stage name (the rule's name where the stage-per-rule workflow has one).
    sensor : str
        'acc', 'gyr' or 'mag'; 'all' for the validation.
    what : str
        What it does, with the paper's equations (the report lists it).
    """

    name: str
    sensor: str
    what: str


#: The calibration stages in run order.
STAGES: dict[str, Stage] = {
    s.name: s
    for s in (
        Stage("mag_step1", "mag", "magnetometer ellipsoid fit (eqs. 17-24)"),
        Stage(
            "mag_step2",
            "mag",
            "magnetometer alignment T_R from the rotation3d phases (eqs. 25-27)",
        ),
        Stage(
            "acc_known_orientation",
            "acc",
            "accelerometer from static faces of known orientation (Ferraris)",
        ),
        Stage("acc_cube", "acc", "accelerometer multi-position fit |a| = g (eq. 32)"),
        Stage(
            "acc_align",
            "acc",
            "accelerometer alignment T_R from the rotation3d phases (eqs. 25-27)",
        ),
        Stage("gyr_bias", "gyr", "gyroscope bias from static data (eqs. 34-35)"),
        Stage("gyr_table", "gyr", "gyroscope rate-table fit (eq. 33)"),
        Stage(
            "gyr_align",
            "gyr",
            "gyroscope alignment T_R from the rotation3d phases (eqs. 28-31)",
        ),
        Stage(
            "gyr_known_rotation",
            "gyr",
            "gyroscope from rotations of known angle (Ferraris; hand turns)",
        ),
        Stage(
            "gyr_reference",
            "gyr",
            "gyroscope scale, non-orthogonality, bias and mounting against an orientation "
            "reference's rotations (motion capture, robot)",
        ),
        Stage(
            "acc_reference",
            "acc",
            "accelerometer from the orientation reference's gravity direction at rests "
            "(positions of known orientation, in the gyroscope's frame B)",
        ),
        Stage(
            "mag_reference",
            "mag",
            "magnetometer alignment T_R to the gyroscope's frame B from the orientation "
            "reference (the field one direction in its world)",
        ),
        Stage(
            "gyr_pose_to_pose",
            "gyr",
            "gyroscope from gravity-direction changes between poses (Tedaldi 2014)",
        ),
        Stage(
            "gyr_scale",
            "gyr",
            "gyroscope scale from acc/mag angles, tool-free (eq. 36)",
        ),
    )
}
#: The validation against the reference, listed after the calibration stages.
VALIDATE = Stage("validate", "all", "validation against the reference")
#: Per sensor, the stages whose result calibrates it, preferred first.
FINAL = {
    "mag": ("mag_step2", "mag_reference", "mag_step1"),
    "acc": ("acc_known_orientation", "acc_align", "acc_reference", "acc_cube"),
    "gyr": (
        "gyr_table",
        "gyr_known_rotation",
        "gyr_reference",
        "gyr_pose_to_pose",
        "gyr_scale",
        "gyr_bias",
    ),
}


def full_protocol_artifacts() -> dict[str, str]:
    """Stage name -> artifact file under ``results/{dataset}/`` of the registered stages that
    the stage-per-rule workflow runs (the nodes of :mod:`imucal.pipeline.graph`), in the
    registry's order, and the validation's."""
    from imucal.pipeline.graph import FULL_PROTOCOL

    files = {name: FULL_PROTOCOL[name].artifact for name in STAGES if name in FULL_PROTOCOL}
    return files | {VALIDATE.name: "validation.json"}


def declared_sensors(dataset, recording: str) -> tuple[str, ...]:
    """Sensors a recording of a dataset holds, from ``dataset.yaml`` alone (before ingest).

    A native raw CSV holds all three; a declared reader the sensors its column maps name.
    """
    declaration = dataset.readers.get(recording)
    if declaration is None:
        return SENSORS

    from imucal.io.readers import declared_entries

    names = {c for entry in declared_entries(declaration) for c in entry.get("columns", {})}
    return tuple(s for s in SENSORS if any(c.startswith(f"{s}_") for c in names))


def is_full_protocol(dataset) -> bool:
    """The paper's protocol: native-format rotation3d and cube with all three sensors.

    Such a session runs the stage-per-rule workflow; any other runs the partial path
    (:func:`imucal.pipeline.partial.run_stages`).
    """
    return all(
        dataset.has(r) and declared_sensors(dataset, r) == SENSORS for r in ("rotation3d", "cube")
    )


def split_held_out(references: Mapping[str, tuple]) -> tuple[list[str], list[str]]:
    """Which recordings may feed a fit, and which are held out for validation only.

    The one place that decides it: a recording whose orientation reference is declared
    ``held_out`` enters no fit at all (neither the fits against the reference nor the ellipsoid,
    the gyroscope bias or any other stage); it is only validated on.

    Parameters
    ----------
    references : mapping of str to (table, metadata)
        Per recording with a reference, its ingested reference and metadata (``held_out``).

    Returns
    -------
    fit, held : list of str
        Recordings in the given order.
    """
    held = [name for name, (_, meta) in references.items() if meta.get("held_out", False)]
    return [name for name in references if name not in held], held
