"""The dataset description (``dataset.yaml``): loading, schema validation and defaults."""

from __future__ import annotations

from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import jsonschema
import yaml

#: Recording names of the native contract, in protocol order.
RECORDING_NAMES = ("rotation3d", "cube", "ratetable", "static", "reference")
#: Recordings in the native IMU CSV format (the reference is an MT Manager export).
IMU_RECORDINGS = ("rotation3d", "cube", "ratetable", "static")


def _schema() -> dict:
    text = resources.files("imucal").joinpath("schemas/dataset.schema.yaml").read_text()
    return yaml.safe_load(text)


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
        SI unit per raw count, keys 'acc', 'gyr', 'mag'.
    range_counts : dict
        Saturation limit of the raw counts per sensor.
    recordings : dict
        Recording name -> file path (absolute).
    ratetable : dict or None
        ``{'axes': [...], 'rates_dps': [...]}`` when the session has a rate table.
    segments : list of dict
        Manual segmentation override (may be empty).
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

    def has(self, recording: str) -> bool:
        return recording in self.recordings


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
    schema = _schema()
    errors = sorted(
        jsonschema.Draft202012Validator(schema).iter_errors(raw), key=lambda e: list(e.path)
    )
    if errors:
        err = errors[0]
        where = "/".join(str(p) for p in err.path) or "(top level)"
        raise ValueError(f"{path}: key '{where}': {err.message}")
    cfg = _with_defaults(schema, raw)
    if "ratetable" in cfg["recordings"] and "ratetable" not in cfg:
        raise ValueError(f"{path}: key 'ratetable': required when recordings/ratetable is given")
    recordings = {name: folder / file for name, file in cfg["recordings"].items()}
    return Dataset(
        name=cfg["name"],
        folder=folder,
        gravity_m_s2=float(cfg["gravity_m_s2"]),
        field_norm=float(cfg["field_norm"]),
        sensitivity={k: float(v) for k, v in cfg["sensitivity"].items()},
        range_counts={k: int(cfg["range_counts"].get(k, 32767)) for k in ("acc", "gyr", "mag")},
        recordings=recordings,
        ratetable=cfg.get("ratetable"),
        segments=list(cfg.get("segments", [])),
    )
