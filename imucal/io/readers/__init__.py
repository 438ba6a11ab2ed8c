"""Declared readers: recordings in other people's formats, described in ``dataset.yaml``.

A recording of ``dataset.yaml`` is either a file name (the native IMU CSV, read by
:func:`imucal.io.read_imu_csv`) or a mapping that declares how to read it
(``docs/data-format.md``, section "Declared recordings"):

* one file: ``reader`` (``table``, ``matlab``, ``hdf5`` or ``netcdf``), ``file`` and a column map;
* ``streams``: one file per sensor (each a one-file entry), merged on time;
* ``parts``: one-file or ``streams`` entries concatenated in time.

This package is the file access of those declarations (like :mod:`imucal.io` for the native
formats): it reads the columns, converts them to the SI units of :mod:`imucal.columns`, applies
the declared axis permutation and signs, and merges streams and parts. It adds no sample and
fills no value: a sensor without a sample at a row's time holds NaN on that row (all three axes).

Every problem raises :class:`DeclarationError` (a declaration that does not fit the file, the
message names the ``dataset.yaml`` key path and the column) or :class:`imucal.io.RawDataError`
(the file breaks its declared format; the message names the file and the line or row).

Each concept in its module, re-exported here: :mod:`.declaration` (the entries, the shared
checks of the target names, the error and the result), :mod:`.recording` (one file, streams,
parts), :mod:`.table` and :mod:`.arrays` (the file formats), :mod:`.conversion` (time, counters,
sensors to SI) and :mod:`.sections` (section lists).
"""

from imucal.io.readers.arrays import CF_SENSOR_UNITS, CF_TIME_UNITS
from imucal.io.readers.conversion import (
    PHYSICAL_MAG_UNITS,
    SENSITIVITY_UNITS,
    UNIT_FACTORS,
    axis_matrix,
)
from imucal.io.readers.declaration import (
    EXTRA_NAME,
    READERS,
    DeclarationError,
    DeclaredRecording,
    declared_entries,
    declared_files,
)
from imucal.io.readers.recording import (
    PART_GAP_S,
    PART_GAP_STEPS,
    merge_streams,
    read_declared,
    read_entry,
)
from imucal.io.readers.sections import FERRARIS_LABELS, SECTION_CSV_OPTIONAL, read_sections
from imucal.io.readers.table import DELIMITERS

__all__ = [
    "CF_SENSOR_UNITS",
    "CF_TIME_UNITS",
    "DELIMITERS",
    "DeclarationError",
    "DeclaredRecording",
    "EXTRA_NAME",
    "FERRARIS_LABELS",
    "PART_GAP_S",
    "PART_GAP_STEPS",
    "PHYSICAL_MAG_UNITS",
    "READERS",
    "SECTION_CSV_OPTIONAL",
    "SENSITIVITY_UNITS",
    "UNIT_FACTORS",
    "axis_matrix",
    "declared_entries",
    "declared_files",
    "merge_streams",
    "read_declared",
    "read_entry",
    "read_sections",
]
