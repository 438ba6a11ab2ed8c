"""imucal: calibration of 9-axis IMUs on a 3-D rotation platform (Zhang et al., 2014).

The import package is ``imucal``; the distribution is ``imu-platform-cal`` (the PyPI name
``imucal`` belongs to an unrelated project by mad-lab-fau).
"""

from importlib.metadata import PackageNotFoundError, version

import lazy_loader

# the names of __init__.pyi, each imported on first use (SPEC 1): a process that needs one
# submodule does not pay for the others' imports
__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
__all__ += ["__version__"]

try:
    __version__ = version("imu-platform-cal")
except PackageNotFoundError:  # running from a source tree that was not installed
    __version__ = "0+unknown"
