"""Ingest of a declared orientation reference (motion capture, robot) recorded with a recording."""

from __future__ import annotations

import pandas as pd

from imucal.io.dataset import Dataset
from imucal.io.orientation import read_orientation_reference


def ingest_orientation_reference(
    recording: str, dataset: Dataset, imucal_version: str
) -> tuple[pd.DataFrame, dict]:
    """Read the orientation reference of one recording into the ingested convention.

    Parameters
    ----------
    recording : str
        A recording whose declaration in ``dataset.yaml`` has a ``reference``.
    dataset : Dataset
    imucal_version : str
        Package version, recorded in the metadata.

    Returns
    -------
    table : DataFrame, shape (n, 5)
        ``t_s`` (s, the reference's clock) and ``q_w..q_z`` (unit, scalar first, body->world;
        NaN rows where tracking was lost).
    metadata : dict
        ``dataset``, ``recording``, ``format`` (``orientation``), ``sha256`` of the first file,
        ``imucal_version`` and the reader's metadata
        (:func:`imucal.io.orientation.read_orientation_reference`).

    Raises
    ------
    ValueError
        If the recording declares no orientation reference (the message lists those that do).
    """
    if recording not in dataset.orientation_references:
        raise ValueError(
            f"{dataset.yaml_path}: recordings.{recording} declares no reference; recordings "
            f"with one: {sorted(dataset.orientation_references)}"
        )
    table, info = read_orientation_reference(
        dataset.orientation_references[recording], where=dataset.reference_where(recording)
    )
    metadata = {
        "dataset": dataset.name,
        "recording": recording,
        "format": "orientation",
        "sha256": info["files"][0]["sha256"],
        "imucal_version": imucal_version,
        **info,
    }
    return table, metadata
