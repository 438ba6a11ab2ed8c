"""Declared orientation references: motion capture or a robot's orientation series.

A recording of ``dataset.yaml`` may declare the orientation reference recorded with it (key
``reference`` inside the recording's declaration, ``docs/data-format.md``): quaternions (scalar
first or last) or rotation matrices, read by any reader of :mod:`imucal.io.readers`, at their
own rate or time base. This module reads it and converts it to one convention: unit
quaternions, scalar first, rotating vectors from the reference's body frame to its world frame.
Rows where tracking was lost stay NaN rows: gaps are kept, never filled. A row is a gap when
any of its components is not finite or all of them are zero (a common "not tracked" value of
motion-capture exports). A quaternion whose norm is within the declared ``unit_tolerance`` of 1
is renormalised (the norm of a pose interpolated component by component, or of a value
rounded in the file, is a little below 1); one beyond it is an error naming the row, as is a
matrix whose ``R^T R`` is farther than it from the identity.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation

from imucal.columns import MATRIX_SOURCE, POSITION, QUAT, QUAT_SOURCE, TIME
from imucal.io.dataset import reference_with_defaults
from imucal.io.readers import DeclarationError, read_entry

#: Keys of a reference declaration that are its reader's (passed to :func:`read_entry`).
READER_KEYS = (
    "reader", "file", "columns", "rate_hz", "delimiter", "skip_lines", "header", "variable",
    "dataset", "transpose", "sort_by_time",
)  # fmt: skip
#: Representations of the orientation and the source columns each needs.
ORIENTATIONS = {"quaternion": QUAT_SOURCE, "matrix": MATRIX_SOURCE}
#: Directions of the declared rotation: it maps body vectors to world vectors, or the reverse.
ROTATES = ("body_to_world", "world_to_body")
#: The convention of the ingested columns, written into the metadata.
CONVENTION = (
    "q_w, q_x, q_y, q_z: unit quaternion, scalar first, rotating vectors from the reference's "
    "body frame to its world frame (v_world = q v_body q*); NaN rows: tracking lost"
)
#: Largest |position| (m) accepted of a declared reference position: a lab or a robot's cell
#: is metres across, so a larger value is another unit (millimetres) or no position.
MAX_POSITION_M = 100.0


def _place(rec: Any, row: int, file: str) -> str:
    """Where a data row is, for a message: the 1-based line of a text file, else the 1-based
    sample (MATLAB and HDF5 files have no lines; a table sorted by time no longer follows its
    lines)."""
    first = rec.metadata.get("first_line")
    if first is not None:
        return f"{file}, line {first + row}"
    return f"{file}, sample {row + 1} (counted from 1)"


def read_orientation_reference(
    declaration: Mapping[str, Any], *, where: str
) -> tuple[pd.DataFrame, dict]:
    """Read a declared orientation reference into unit quaternions (scalar first, body->world).

    Parameters
    ----------
    declaration : mapping
        The ``reference`` mapping of a recording in ``dataset.yaml`` with its ``file`` made
        absolute: reader keys (:data:`READER_KEYS`), ``orientation`` (``quaternion`` or
        ``matrix``), ``scalar`` (``first`` or ``last``, quaternions only), ``rotates``
        (:data:`ROTATES`), ``up`` (the world axis pointing up, e.g. ``+z``); optionally the
        body's position in the reference's world, columns ``p_x, p_y, p_z`` (m).
    where : str
        ``"<dataset.yaml>: recordings.<name>.reference"``, the prefix of every error message.

    Returns
    -------
    table : DataFrame, shape (n, 5) or (n, 8)
        ``t_s`` (s, the reference's own clock) and ``q_w, q_x, q_y, q_z``; all four NaN on the
        rows where the source has no orientation (a non-finite component, or all zeros).
        With a declared position also ``p_x, p_y, p_z`` (m, the reference's world frame; NaN
        where the orientation or a component is missing).
    metadata : dict
        ``reader``, ``files``, ``convention``, ``orientation``, ``scalar``, ``rotates``, ``up``,
        ``held_out``, ``rows``, ``gap_rows``, ``max_norm_error``, ``unit_tolerance``,
        ``position`` (whether the position is declared).

    Raises
    ------
    DeclarationError
        Columns that do not match ``orientation``, a quaternion farther from unit norm than
        ``unit_tolerance``, a matrix that is not a rotation; a position declared with fewer
        than its three components, without a finite value, or beyond :data:`MAX_POSITION_M`.
    RawDataError, FileNotFoundError
        From the reader.
    """
    declaration = reference_with_defaults(dict(declaration))
    tolerance = float(declaration["unit_tolerance"])
    kind = declaration.get("orientation")
    if kind not in ORIENTATIONS:
        raise DeclarationError(f"{where}.orientation", f"{kind!r}", f"one of {list(ORIENTATIONS)}")
    rotates = declaration.get("rotates")
    if rotates not in ROTATES:
        raise DeclarationError(f"{where}.rotates", f"{rotates!r}", f"one of {list(ROTATES)}")
    scalar = declaration.get("scalar")
    if kind == "quaternion" and scalar not in ("first", "last"):
        raise DeclarationError(
            f"{where}.scalar", f"{scalar!r}", "first (w, x, y, z) or last (x, y, z, w)"
        )
    if kind == "matrix" and scalar is not None:
        raise DeclarationError(f"{where}.scalar", "scalar with a matrix", "it for quaternions only")
    needed = ORIENTATIONS[kind]
    columns = dict(declaration.get("columns") or {})
    given = sorted(set(columns) - {TIME, *POSITION})
    if given != sorted(needed):
        raise DeclarationError(
            f"{where}.columns",
            f"targets {given}",
            f"exactly {', '.join(needed)} (and optionally t_s, p_x, p_y, p_z) for orientation "
            f"{kind}",
        )
    position = sorted(set(columns) & set(POSITION))
    if position and position != sorted(POSITION):
        raise DeclarationError(
            f"{where}.columns",
            f"position targets {position}",
            "all three of p_x, p_y, p_z (the body's position in the world frame, m) or none",
        )
    entry = {k: declaration[k] for k in READER_KEYS if k in declaration}
    rec = read_entry(entry, where=where)
    values = rec.table[list(needed)].to_numpy(dtype=float)
    # a gap: tracking lost, written as NaN, inf or all zeros (or with only some components)
    ok = np.isfinite(values).all(axis=1) & np.any(values != 0.0, axis=1)
    if not ok.any():
        raise DeclarationError(f"{where}.columns", f"no orientation in {entry['file']}", "some")
    quat = np.full((values.shape[0], 4), np.nan)
    if kind == "quaternion":
        q = values[ok] if scalar == "first" else values[ok][:, [3, 0, 1, 2]]
        norm = np.linalg.norm(q, axis=1)
        error = np.abs(norm - 1.0)
        worst = int(np.argmax(error))
        if error[worst] > tolerance:
            row = int(np.flatnonzero(ok)[worst])
            raise DeclarationError(
                f"{where}.columns",
                f"{_place(rec, row, entry['file'])} has |q| = {norm[worst]:.6g}",
                f"unit quaternions (| |q| - 1 | <= {where}.unit_tolerance = {tolerance:g}); "
                "check that the columns are the four components of one quaternion, or declare "
                "a larger unit_tolerance",
            )
        quat[ok] = q / norm[:, None]
        max_error = float(error.max())
    else:
        matrices = values[ok].reshape(-1, 3, 3)
        gram = np.einsum("nji,njk->nik", matrices, matrices) - np.eye(3)
        error = np.max(np.abs(gram), axis=(1, 2))
        det = np.linalg.det(matrices)
        bad = (error > tolerance) | (det <= 0)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            row = int(np.flatnonzero(ok)[i])
            raise DeclarationError(
                f"{where}.columns",
                f"{_place(rec, row, entry['file'])} is not a rotation matrix (max |R^T R - I| = "
                f"{error[i]:.3g}, det {det[i]:.6g})",
                f"rotation matrices given row by row as r_11, r_12, ..., r_33 "
                f"({where}.unit_tolerance = {tolerance:g})",
            )
        xyzw = Rotation.from_matrix(matrices).as_quat()
        quat[ok] = xyzw[:, [3, 0, 1, 2]]
        max_error = float(error.max())
    if rotates == "world_to_body":
        quat[ok, 1:] *= -1.0  # the conjugate: the inverse rotation
    table = pd.DataFrame({TIME: rec.table[TIME].to_numpy(), **dict(zip(QUAT, quat.T))})
    if position:
        table[list(POSITION)] = _positions(rec, ok, entry["file"], where)
    metadata = {
        "reader": rec.metadata["reader"],
        "files": rec.metadata["files"],
        "convention": CONVENTION,
        "orientation": kind,
        "scalar": scalar,
        "rotates": rotates,
        "up": declaration.get("up"),
        "held_out": bool(declaration.get("held_out", False)),
        "rows": int(len(table)),
        "gap_rows": int(np.count_nonzero(~ok)),
        "max_norm_error": max_error,
        "unit_tolerance": tolerance,
        "position": bool(position),
    }
    return table, metadata


def _positions(rec: Any, ok: np.ndarray, file: str, where: str) -> np.ndarray:
    """The declared positions (m, shape (n, 3)), NaN where the orientation is a gap or a
    component is not finite; an error when none is finite or one is beyond
    :data:`MAX_POSITION_M`."""
    values = rec.table[list(POSITION)].to_numpy(dtype=float)
    values[~ok] = np.nan
    values[~np.isfinite(values).all(axis=1)] = np.nan
    present = np.isfinite(values).all(axis=1)
    if not present.any():
        raise DeclarationError(
            f"{where}.columns",
            f"no finite position p_x, p_y, p_z in {file} at a row with an orientation",
            "the body's position in the world frame (m) where the orientation is tracked",
        )
    size = np.linalg.norm(np.where(present[:, None], values, 0.0), axis=1)
    worst = int(np.argmax(size))
    if size[worst] > MAX_POSITION_M:
        raise DeclarationError(
            f"{where}.columns",
            f"{_place(rec, worst, file)} has |p| = {size[worst]:.6g}",
            f"positions in metres within {MAX_POSITION_M:g} m of the world's origin (a value "
            "in millimetres must be converted in the file or left undeclared)",
        )
    return values
