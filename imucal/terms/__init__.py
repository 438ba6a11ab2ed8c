"""The optional model terms and the closed loop that estimates them where the gap diagnosis
accepts their effect.

The contract of a term (:mod:`.term`), the terms themselves, one module each (:mod:`.model`:
correction, variance, dict form, report rows, export note), and their registry
(:mod:`.registry`). Their estimators: temperature polynomials (:mod:`imucal.gap.temperature`), the
gyroscope's g-sensitivity (:mod:`.gsensitivity`), the accelerometer's lever arm on the rate
table (:mod:`.leverarm`), the magnetometer's delay (:mod:`.magdelay`); the temperature terms
held out across static poses (:mod:`.poseholdout`, its intervals over long blocks in
:mod:`.blockspread`), the switch per term (:mod:`.selection`) and
the loop that folds them into the calibration (:mod:`.loop`).
"""

import lazy_loader

# the names of __init__.pyi, each imported on first use (SPEC 1): a process that needs one
# submodule does not pay for the others' imports
__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
