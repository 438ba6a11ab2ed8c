"""Noise characterisation of a static recording: overlapping Allan deviation with confidence
intervals (:mod:`imucal.noise.allan`), the IEEE Std 952 / 1293 terms fitted to it
(:mod:`imucal.noise.fit`) and the stage that runs both on every sensor axis
(:mod:`imucal.noise.characterise`)."""

import lazy_loader

# the names of __init__.pyi, each imported on first use (SPEC 1): a process that needs one
# submodule does not pay for the others' imports
__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
