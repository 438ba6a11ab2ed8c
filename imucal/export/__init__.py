"""Exports of a calibration and its noise to the tools users feed: Kalibr
(:mod:`imucal.export.kalibr`), OpenVINS (:mod:`imucal.export.openvins`) and the ROS
``sensor_msgs/Imu`` covariances (:mod:`imucal.export.ros`); :func:`export_files` renders the files
of one format. Conventions and their sources: ``docs/exports.md``."""

import lazy_loader

# the names of __init__.pyi, each imported on first use (SPEC 1): a process that needs one
# submodule does not pay for the others' imports
__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
