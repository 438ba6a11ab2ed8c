"""The closed loop: the optional model terms estimated where the gap diagnosis accepts their
effect, and folded into the calibration.

The terms themselves (their contract, one module each, their registry) are part of the model
(:mod:`imucal.modelterms`). Here: their estimators, found by the term's name
(:mod:`.estimators`: temperature polynomials from :mod:`imucal.gap.temperature`, the
gyroscope's g-sensitivity :mod:`.gsensitivity`, the accelerometer's lever arm on the rate table
:mod:`.leverarm`, the magnetometer's delay :mod:`.magdelay`); the temperature terms held out
across static poses (:mod:`.poseholdout`, its intervals over long blocks in
:mod:`.blockspread`); the switch per term (:mod:`.selection`) and the loop that folds them into
the calibration (:mod:`.loop`).
"""

import lazy_loader

# the names of __init__.pyi, each imported on first use (SPEC 1): a process that needs one
# submodule does not pay for the others' imports
__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
