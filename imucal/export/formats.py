"""The export formats and the files each writes (what the workflow and the command line offer,
known without importing the exporters)."""

#: Export format -> the files it writes.
FORMATS = {
    "kalibr": ("kalibr_imu.yaml", "kalibr_imu_chain.yaml"),
    "openvins": ("openvins_kalibr_imu_chain.yaml",),
    "ros": ("ros_imu_covariance.yaml",),
}
