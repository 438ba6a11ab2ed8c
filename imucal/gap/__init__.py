"""Sim-to-real gap diagnosis: where a recorded session departs from its twin, which
unmodelled effect causes it, and how far adding the effect to the twin closes it.

Modules: :mod:`.pipeline` (the calibration stages in process), :mod:`.twin` (the session's twin
under the paper's model), :mod:`.statistics` (the locations of the gap map), :mod:`.null`
(replicas, scores, Holm, total gap), :mod:`.effects` (estimators and signatures),
:mod:`.attribution` (held-out forward selection), :mod:`.diagnosis` (diagnosis.json),
:mod:`.figures` (report section), :mod:`.blind` (the blind check), :mod:`.stress` (the stress
set), :mod:`.detection` (detection limits). See docs/gap.md.
"""

from imucal.gap.diagnosis import FORMAT_VERSION, diagnose

__all__ = ["FORMAT_VERSION", "diagnose"]
