"""The dataset description (``dataset.yaml``): loading, schema validation and defaults."""

from __future__ import annotations

import difflib
import functools
import os
import re
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import jsonschema
import yaml

from imucal.constants import REFERENCE


@functools.cache
def _validator() -> jsonschema.Draft202012Validator:
    """The schema's validator, built once per process (a workflow reads every dataset.yaml)."""
    text = resources.files("imucal.io").joinpath("schemas/dataset.schema.yaml").read_text()
    return jsonschema.Draft202012Validator(yaml.safe_load(text))


def _with_defaults(schema: dict, instance: dict) -> dict:
    """Fill in the ``default`` of every absent property, recursively (objects only)."""
    out = dict(instance)
    for key, sub in schema.get("properties", {}).items():
        if key not in out and "default" in sub:
            out[key] = sub["default"]
        if isinstance(out.get(key), dict) and sub.get("type") == "object":
            out[key] = _with_defaults(sub, out[key])
    return out


@dataclass(frozen=True)
class Dataset:
    """A calibration session on disk.

    Attributes
    ----------
    name : str
    folder : Path
    gravity_m_s2 : float
    field_norm : float
        Norm of the magnetic field after sensitivity (1 for a normalised magnetometer).
    sensitivity : dict
        SI unit per raw count of the native IMU CSV, keys 'acc', 'gyr', 'mag' (empty when no
        recording is a native CSV).
    range_counts : dict
        Saturation limit of the raw counts per sensor: ``|counts| >=`` it is clipped (for a
        declared ``[lowest, highest]`` pair the smaller of ``-lowest`` and ``highest``).
    recordings : dict
        Recording name -> its (first) file, absolute. For a declared recording the other files
        are in ``readers``; :meth:`recording_files` lists all.
    ratetable : dict or None
        ``{'axes': [...], 'rates_dps': [...]}`` when the session has a rate table.
    segments : list of dict
        Manual segmentation override (may be empty).
    readers : dict
        Recording name -> reader declaration (``file`` paths absolute) for the recordings
        declared as a mapping in ``dataset.yaml``; native recordings are absent.
    field_norm_t : float or None
        Local field norm in tesla (``field_norm_t``), for magnetometers in physical units.
    sections : dict or None
        The ``sections`` declaration (``file`` absolute), or None.
    yaml_path : Path or None
        The ``dataset.yaml`` file (for messages).
    count_range : dict
        Sensor -> ``(lowest, highest)`` raw count its ADC can output (``range_counts``: ``n``
        is ``(-n, n)``, a pair as declared). Readings at a limit are clipped samples; counts
        beyond it are refused at ingest.
    orientation_references : dict
        Recording name -> the declaration of the orientation reference recorded with it (the
        ``reference`` key of its declaration, ``file`` absolute); read by
        :func:`imucal.io.orientation.read_orientation_reference`.
    simulated : dict or None
        The ``simulated`` declaration (``by``: what rendered the recordings; ``truth``: the
        ground truth's file, absolute) of a session rendered by a simulator; None for a
        recorded session.
    """

    name: str
    folder: Path
    gravity_m_s2: float
    field_norm: float
    sensitivity: dict
    range_counts: dict
    recordings: dict
    ratetable: dict | None
    segments: list
    readers: dict = field(default_factory=dict)
    field_norm_t: float | None = None
    sections: dict | None = None
    yaml_path: Path | None = None
    count_range: dict = field(default_factory=dict)
    orientation_references: dict = field(default_factory=dict)
    simulated: dict | None = None

    def has(self, recording: str) -> bool:
        return recording in self.recordings

    def reference_where(self, recording: str) -> str:
        """Prefix of the error messages of a recording's orientation reference."""
        return f"{self.yaml_path}: recordings.{recording}.reference"

    def recording_files(self, recording: str) -> list[Path]:
        """Every file a recording reads (the Snakemake inputs of its ingest), in order.

        Includes the section list file when ``sections`` names this recording.

        Raises
        ------
        KeyError
            If the dataset has no such recording (the message lists the ones it has).
        """
        from imucal.io.readers import declared_files  # readers import io, which is heavier

        if recording not in self.recordings:
            raise KeyError(
                f"dataset {self.name!r} has no recording {recording!r}; it has "
                f"{sorted(self.recordings)}"
            )
        if recording in self.readers:
            files = declared_files(self.readers[recording])
        else:
            files = [self.recordings[recording]]
        if self.sections and self.sections["recording"] == recording and "file" in self.sections:
            files.append(Path(self.sections["file"]))
        return files


def read_dataset(folder: str | Path) -> Dataset:
    """Read and validate ``folder/dataset.yaml``.

    Raises
    ------
    FileNotFoundError
        If the folder or its ``dataset.yaml`` does not exist.
    ValueError
        If the file is not valid YAML or breaks the schema; the message names the key path.
    """
    folder = Path(folder).resolve()
    path = folder / "dataset.yaml"
    if not path.is_file():
        raise FileNotFoundError(f"{path}: dataset description not found")
    try:
        raw = yaml.safe_load(path.read_text())
    except yaml.YAMLError as err:
        raise ValueError(f"{path}: not valid YAML: {err}") from None
    if not isinstance(raw, dict):
        raise ValueError(f"{path}: expected a mapping at the top level, got {type(raw).__name__}")
    validator = _validator()
    errors = sorted(validator.iter_errors(raw), key=lambda e: list(e.path))
    if errors:
        err = errors[0]
        where = "/".join(str(p) for p in err.path) or "(top level)"
        unknown = _unknown_keys(err)
        if unknown:
            raise ValueError(f"{path}: {unknown}") from None
        raise ValueError(f"{path}: key '{where}': {err.message}")
    cfg = _with_defaults(validator.schema, raw)
    if "ratetable" in cfg["recordings"] and "ratetable" not in cfg:
        raise ValueError(f"{path}: key 'ratetable': required when recordings/ratetable is given")
    recordings: dict[str, Path] = {}
    readers: dict[str, dict] = {}
    references: dict[str, dict] = {}
    for name, value in cfg["recordings"].items():
        if isinstance(value, str):
            recordings[name] = _resolve(folder, value)
            continue
        value = dict(value)
        if "reference" in value:
            references[name] = _orientation_reference(
                value.pop("reference"), value, folder, f"{path}: recordings.{name}"
            )
        readers[name] = _declaration(value, folder, f"{path}: recordings.{name}", top=True)
        recordings[name] = Path(_first_file(readers[name]))
    native = [n for n in recordings if n not in readers and n != REFERENCE]
    if native and "sensitivity" not in cfg:
        raise ValueError(
            f"{path}: key 'sensitivity': required because recordings.{native[0]} is a native "
            "IMU CSV in raw counts"
        )
    sections = cfg.get("sections")
    if sections is not None:
        sections = _sections(dict(sections), folder, recordings, f"{path}: sections")
    manual = list(cfg.get("segments", []))
    unknown = sorted({e["recording"] for e in manual} - set(recordings))
    if unknown:
        raise ValueError(
            f"{path}: key 'segments': recording(s) {unknown} not in recordings {sorted(recordings)}"
        )
    count_range = _count_range(validator.schema, cfg["range_counts"], f"{path}: key 'range_counts")
    return Dataset(
        name=cfg["name"],
        folder=folder,
        gravity_m_s2=float(cfg["gravity_m_s2"]),
        field_norm=float(cfg["field_norm"]),
        sensitivity={k: float(v) for k, v in cfg.get("sensitivity", {}).items()},
        range_counts={k: min(-lo, hi) for k, (lo, hi) in count_range.items()},
        recordings=recordings,
        ratetable=cfg.get("ratetable"),
        segments=manual,
        readers=readers,
        field_norm_t=float(cfg["field_norm_t"]) if "field_norm_t" in cfg else None,
        sections=sections,
        yaml_path=path,
        count_range=count_range,
        orientation_references=references,
        simulated=_simulated(cfg.get("simulated"), folder, path),
    )


def _simulated(declared: dict | None, folder: Path, path: Path) -> dict | None:
    """The ``simulated`` declaration with its truth file made absolute (and checked)."""
    if declared is None:
        return None
    out = dict(declared)
    if "truth" in out:
        truth = _resolve(folder, out["truth"])
        if not truth.is_file():
            raise FileNotFoundError(
                f"{path}: key 'simulated/truth': {out['truth']!r} is not a file in {folder}; "
                "expected the file with the ground truth the data were rendered from"
            )
        out["truth"] = truth
    return out


def _unknown_keys(err: jsonschema.ValidationError) -> str | None:
    """For a key the schema does not know (``additionalProperties``): which, where, and the
    closest known key (a typo); None for any other error."""
    if err.validator != "additionalProperties" or not isinstance(err.instance, dict):
        return None
    known = sorted(err.schema.get("properties", {}))
    patterns = list(err.schema.get("patternProperties", {}))
    extra = [
        k for k in err.instance if k not in known and not any(re.match(p, k) for p in patterns)
    ]
    if not extra:
        return None
    parent = "/".join(str(p) for p in err.path)
    parts = []
    for key in extra:
        name = f"{parent}/{key}" if parent else key
        close = difflib.get_close_matches(str(key), known, n=1, cutoff=0.6)
        hint = f", did you mean {close[0]!r}?" if close else "."
        parts.append(f"key {name!r} is not a known key here{hint}")
    notes = " (keys starting with 'x-' are free for notes)" if "^x-" in patterns else ""
    return f"{' '.join(parts)} Known keys here: {', '.join(known)}{notes}."


def _count_range(schema: dict, declared: dict, where: str) -> dict[str, tuple[int, int]]:
    """``range_counts`` as ``(lowest, highest)`` count per sensor (``n``: ``(-n, n)``)."""
    out = {}
    for sensor, sub in schema["properties"]["range_counts"]["properties"].items():
        value = declared.get(sensor, sub["default"])
        if isinstance(value, int):
            out[sensor] = (-value, value)
            continue
        lo, hi = (int(v) for v in value)
        if not lo < 0 < hi:
            raise ValueError(
                f"{where}/{sensor}': [{lo}, {hi}]; expected [lowest, highest] with "
                "lowest < 0 < highest"
            )
        out[sensor] = (lo, hi)
    return out


def _resolve(folder: Path, file: str) -> Path:
    """A path of dataset.yaml, relative to the dataset folder, normalised (``..`` collapsed)."""
    return Path(os.path.normpath(folder / file))


def _first_file(declaration: dict) -> str:
    if "parts" in declaration:
        return _first_file(declaration["parts"][0])
    if "streams" in declaration:
        return declaration["streams"][0]["file"]
    return declaration["file"]


_ONE_FILE_KEYS = ("reader", "file")


def _declaration(value: dict, folder: Path, where: str, top: bool) -> dict:
    """Check the structure of a reader declaration; make its file paths absolute.

    A one-file entry has ``reader`` and ``file``; ``streams`` holds one-file entries; ``parts``
    (top level only) holds one-file or ``streams`` entries. Exactly one of the three per level.
    """
    kinds = [k for k in ("file", "streams", "parts") if k in value]
    allowed = ("file", "streams", "parts") if top else ("file", "streams")
    if len(kinds) != 1 or kinds[0] not in allowed:
        raise ValueError(
            f"{where}: has {kinds or 'none'} of {list(allowed)}; expected exactly one of them"
        )
    out = dict(value)
    if not top and "reference" in value:
        raise ValueError(
            f"{where}.reference: inside a stream or part; expected it at the recording's top level"
        )
    if "file" in value:
        if "reader" not in value:
            raise ValueError(f"{where}.reader: missing; expected table, matlab or hdf5")
        out["file"] = str(_resolve(folder, value["file"]))
        return out
    others = sorted(set(value) - {kinds[0], "description"})
    if others:
        raise ValueError(
            f"{where}: keys {others} beside {kinds[0]}; expected them inside each entry of "
            f"{kinds[0]}"
        )
    if "streams" in value:
        out["streams"] = []
        for i, s in enumerate(value["streams"]):
            if "file" not in s:
                raise ValueError(f"{where}.streams[{i}]: no file; expected a one-file entry")
            out["streams"].append(_declaration(s, folder, f"{where}.streams[{i}]", top=False))
    else:
        out["parts"] = [
            _declaration(p, folder, f"{where}.parts[{i}]", top=False)
            for i, p in enumerate(value["parts"])
        ]
    return out


def _orientation_reference(reference: dict, recording: dict, folder: Path, where: str) -> dict:
    """The orientation reference of a recording, its file absolute.

    Only a recording on one time base (one file or streams) can carry one: parts are shifted in
    time at ingest, which the reference's clock would not follow.
    """
    if "parts" in recording:
        raise ValueError(
            f"{where}.reference: beside parts; expected it on a recording of one file or of "
            "streams (give each part's recording its own reference)"
        )
    out = reference_with_defaults(reference)
    out["file"] = str(_resolve(folder, reference["file"]))
    return out


def reference_with_defaults(reference: dict) -> dict:
    """An orientation reference declaration with the schema's defaults of its absent keys
    (``held_out``, ``unit_tolerance``): the schema is their only source."""
    return _with_defaults(_validator().schema["$defs"]["orientation_reference"], reference)


def _sections(sections: dict, folder: Path, recordings: dict, where: str) -> dict:
    if sections["recording"] not in recordings:
        raise ValueError(
            f"{where}.recording: {sections['recording']!r} is not in recordings "
            f"{sorted(recordings)}; expected one of them"
        )
    has_file, has_column = "file" in sections, "from_column" in sections
    if has_file == has_column:
        raise ValueError(f"{where}: expected exactly one of file and from_column")
    if has_file:
        sections["file"] = str(_resolve(folder, sections["file"]))
    return sections
