"""The export formats and the files each writes (what the workflow and the command line offer,
known without importing the exporters).

Each format's files carry the name its tool looks for: Kalibr's IMU configuration ``imu.yaml``
(its documentation's name for ``--imu``) and its results file ``<bag>-imu.yaml`` (here with
``imucal`` for the bag), OpenVINS's ``kalibr_imu_chain.yaml`` (the name its ``estimator_config.yaml``
gives ``relative_config_imu``). The workflow writes each format into its own folder,
``results/{dataset}/export/{format}/``, so that the names can be the tools' own.
"""

#: Export format -> the files it writes.
FORMATS = {
    "kalibr": ("imu.yaml", "imucal-imu.yaml"),
    "openvins": ("kalibr_imu_chain.yaml",),
    "ros": ("imu_covariance.yaml",),
}
