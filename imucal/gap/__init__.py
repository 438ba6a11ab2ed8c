"""Sim-to-real gap diagnosis: where a recorded session departs from its twin, which
unmodelled effect causes it, and how far adding the effect to the twin closes it.

Modules: :mod:`.twin` (the session's twin under the paper's model and its replicas; the static
recording's twin in :mod:`.statictwin`), :mod:`.statistics` (the catalogue and the locations of
a full session's gap map; the per-stage statistics in :mod:`.locations`, the session's rows,
halves and resting means in :mod:`.session`), :mod:`.streams` (a static recording's streams and
locations), :mod:`.motion` (recordings with an orientation reference; their locations and
estimators in :mod:`.motionstats`, their twin in :mod:`.motiontwin`), :mod:`.null` (scores, Holm, total gap),
:mod:`.effects` (the effect model), :mod:`.library` (one spec per effect: every scope's
estimator and signature or the reason it cannot be observed), :mod:`.attribution` (held-out
forward selection), :mod:`.diagnosis` (diagnosis.json: one assembly for both twins),
:mod:`.static` (what a static recording can show: the partial session's diagnosis),
:mod:`.figures` (the checks' pages), :mod:`.blind` (the blind check), :mod:`.stress` (the stress
set), :mod:`.detection` (detection limits), :mod:`.checks` (scoring the checks). See docs/gap.md.
"""

import lazy_loader

# the names of __init__.pyi, each imported on first use (SPEC 1): a process that needs one
# submodule does not pay for the others' imports
__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
