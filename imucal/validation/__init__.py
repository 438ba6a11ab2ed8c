"""Validation against a reference IMU: time base (``timing``), mounting (``mounting``) and the
metrics before and after calibration (``metrics``).
"""

import lazy_loader

# the names of __init__.pyi, each imported on first use (SPEC 1): a process that needs one
# submodule does not pay for the others' imports
__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
