"""The stages of the workflow, as functions of their input tables: one function per rule of the
paper's stage-per-rule path.

Each function is what one rule runs: it cuts the segments it needs out of the ingested (or
low-pass filtered) tables, calls the fits of :mod:`imucal.fits` and returns a JSON-ready artifact
(and figures, never saved here). Stages exchange their results through these artifacts, so one
stage can be rerun on new data. The in-process chain (:mod:`imucal.pipeline.full`) and the partial
path (:mod:`imucal.pipeline.partial`) call the same functions, so a stage is written once.

The functions live in one module per sensor or role and are re-exported here:
:mod:`.accelerometer` (cube fit, alignment, the cube's calibration and quality),
:mod:`.gyroscope` (bias, alignment, rate table), :mod:`.toolfree` (the scale without tools,
eq. 36), :mod:`.magnetometer` (steps 1 and 2), :mod:`.calibration` (the gyroscope's and the
whole calibration, its application, the validation and their figures) and :mod:`.common` (what
they share).
"""

import lazy_loader

# the names of __init__.pyi, each imported on first use (SPEC 1): a process that needs one
# submodule does not pay for the others' imports
__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
