"""Ingest: raw logs to SI-unit tables (``recording``), the checks of their content carried over
batches (``checks``), the summary (``summary``), the packet counter and receive timestamps
(``timebase``), declared orientation references (``orientation``).
"""

import lazy_loader

# the names of __init__.pyi, each imported on first use (SPEC 1): a process that needs one
# submodule does not pay for the others' imports
__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
