# Noise characterisation of the static recording (overlapping Allan deviation, IEEE 952 terms;
# imucal.noise) and the exports of the calibration with its noise to Kalibr, OpenVINS and ROS
# (imucal.export, docs/exports.md).


rule noise:
    input:
        unpack(noise_input),
    output:
        noise=report(
            "results/{dataset}/noise.json",
            caption="../report/noise.rst",
            category="Noise and exports",
        ),
        figure=report(
            "results/{dataset}/figures/noise_allan.png",
            caption="../../imucal/report/captions/noise_allan.rst",
            category="Noise and exports",
        ),
    log:
        "results/{dataset}/logs/noise.log",
    benchmark:
        "results/{dataset}/benchmarks/noise.tsv"
    conda:
        "../envs/imucal.yaml"
    params:
        recording=noise_setting("recording"),
        window_s=noise_setting("window_s"),
        min_duration_s=noise_setting("min_duration_s"),
        level=noise_setting("level"),
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/noise.py"


rule export:
    input:
        calibration=calibration_of,
        noise="results/{dataset}/noise.json",
    output:
        kalibr_imu=report(
            "results/{dataset}/export/kalibr/imu.yaml",
            caption="../report/exports.rst",
            category="Noise and exports",
            subcategory="Kalibr",
        ),
        kalibr_results=report(
            "results/{dataset}/export/kalibr/imucal-imu.yaml",
            caption="../report/exports.rst",
            category="Noise and exports",
            subcategory="Kalibr",
        ),
        openvins=report(
            "results/{dataset}/export/openvins/kalibr_imu_chain.yaml",
            caption="../report/exports.rst",
            category="Noise and exports",
            subcategory="OpenVINS",
        ),
        ros=report(
            "results/{dataset}/export/ros/imu_covariance.yaml",
            caption="../report/exports.rst",
            category="Noise and exports",
            subcategory="ROS",
        ),
    log:
        "results/{dataset}/logs/export.log",
    # off the way to calibration.json: runs on a core the stages leave free
    priority: -1
    conda:
        "../envs/imucal.yaml"
    params:
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/export.py"
