"""Exports to Kalibr, OpenVINS and ROS: the receiving tool's own equation, applied to the
exported numbers, gives our calibrated samples; files load with PyYAML with the keys each tool
reads; every value round-trips."""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml

from imucal.cli import main
from imucal.columns import ACC, GYR, TIME
from imucal.export import (
    FORMATS,
    export_files,
    lower_times_rotation,
    noise_parameters,
    rotation_times_lower,
)
from imucal.noise import characterise_noise, sensor_noise

RATE = 100.0
#: Keys Kalibr reads from imu.yaml (kalibr_common/ConfigReader.py, ImuParameters).
KALIBR_IMU_KEYS = {
    "accelerometer_noise_density",
    "accelerometer_random_walk",
    "gyroscope_noise_density",
    "gyroscope_random_walk",
    "rostopic",
    "update_rate",
}
#: Keys of Kalibr's scale-misalignment imu entry (IccSensors.py, IccImu / IccScaledMisalignedImu).
KALIBR_CHAIN_KEYS = KALIBR_IMU_KEYS | {
    "T_i_b",
    "time_offset",
    "model",
    "accelerometers",
    "gyroscopes",
}
#: Keys of imu0 in OpenVINS's config/*/kalibr_imu_chain.yaml (read in VioManagerOptions.h).
OPENVINS_KEYS = KALIBR_IMU_KEYS | {"T_i_b", "time_offset", "model", "Tw", "R_IMUtoGYRO", "Ta",
                                   "R_IMUtoACC", "Tg"}  # fmt: skip
#: The three covariance fields of sensor_msgs/Imu (ros/common_msgs, sensor_msgs/msg/Imu.msg).
ROS_KEYS = {"orientation_covariance", "angular_velocity_covariance",
            "linear_acceleration_covariance"}  # fmt: skip


def _rotation(rotvec):
    from scipy.spatial.transform import Rotation

    return Rotation.from_rotvec(rotvec).as_matrix()


@pytest.fixture(scope="module")
def calibration():
    """A calibration with scale errors, non-orthogonality and a rotation in both sensors."""
    rng = np.random.default_rng(7)
    cal = {"format_version": 1}
    for sensor, unit, bias in (("acc", "m/s^2", 0.2), ("gyr", "rad/s", 0.02)):
        shear = np.eye(3) + np.triu(rng.normal(0, 0.02, (3, 3)), 1)
        matrix = _rotation(rng.normal(0, 0.05, 3)) @ shear @ np.diag(1 + rng.normal(0, 0.03, 3))
        cal[sensor] = {"bias": rng.normal(0, bias, 3).tolist(), "matrix": matrix.tolist(),
                       "unit_in": unit}  # fmt: skip
    return cal


#: A g-sensitivity (rad/s per m/s^2, frame B) and a temperature term the tools cannot carry.
G = np.array([[2e-4, -3e-5, 1e-5], [4e-5, -1.5e-4, 2e-5], [-1e-5, 3e-5, 1e-4]])
TEMPERATURE = {"gyr": {"reference_c": 25.0, "span_c": [20.0, 30.0], "margin_c": 1.0,
                       "bias": [[1e-4, 1e-4, 1e-4]], "scale": []}}  # fmt: skip


@pytest.fixture(scope="module")
def with_terms(calibration):
    """The calibration with a g-sensitivity and a temperature term (format 2)."""
    return {**calibration, "format_version": 2,
            "terms": {"g_sensitivity": {"matrix": G.tolist()}, "temperature": TEMPERATURE}}  # fmt: skip


@pytest.fixture(scope="module")
def noise():
    """noise.json of 20 min of white noise (per-axis densities) with a bias random walk."""
    rng = np.random.default_rng(2)
    n = int(1200 * RATE)
    cols = {TIME: np.arange(n) / RATE}
    densities = {"acc": (2e-3, 2.5e-3, 3e-3), "gyr": (1.5e-4, 1.7e-4, 2e-4)}
    for sensor, names in (("acc", ACC), ("gyr", GYR)):
        for name, d in zip(names, densities[sensor]):
            walk = 1e-4 * np.sqrt(1 / RATE) * np.cumsum(rng.standard_normal(n))
            cols[name] = d * np.sqrt(RATE) * rng.standard_normal(n) + walk
    return characterise_noise(cols.__getitem__, list(cols), recording="static", window_s=None,
                              min_duration_s=30.0, level=0.683)  # fmt: skip


@pytest.fixture(scope="module")
def files(calibration, noise):
    """Every export, loaded back with PyYAML."""
    out = {}
    for fmt in FORMATS:
        for name, text in export_files(fmt, calibration, noise).items():
            out[name] = yaml.safe_load(text)
    return out


@pytest.fixture(scope="module")
def raw():
    """Raw samples (sensor axes, SI) of specific force and rate."""
    rng = np.random.default_rng(4)
    return {"acc": rng.normal(0, 9.81, (500, 3)), "gyr": rng.normal(0, 2.0, (500, 3))}


def _ours(calibration, sensor, samples, acc=None):
    """Our calibrated samples; the gyroscope's less ``G a_B`` when the model has a
    g-sensitivity (``acc``: the raw specific force of the same samples)."""
    c = calibration[sensor]
    out = (np.array(c["matrix"]) @ (samples - np.array(c["bias"])).T).T
    g = calibration.get("terms", {}).get("g_sensitivity")
    if sensor == "gyr" and g is not None:
        out -= _ours(calibration, "acc", acc) @ np.array(g["matrix"]).T
    return out


@pytest.fixture(scope="module")
def files_with_terms(with_terms, noise):
    out = {}
    for fmt in FORMATS:
        for name, text in export_files(fmt, with_terms, noise).items():
            out[name] = text
    return out


@pytest.mark.parametrize("split", [lower_times_rotation, rotation_times_lower])
def test_triangular_splits_rebuild_the_matrix(split, calibration):
    for sensor in ("acc", "gyr"):
        m = np.array(calibration[sensor]["matrix"])
        a, b = split(m)
        lower, rot = (a, b) if split is lower_times_rotation else (b, a)
        np.testing.assert_allclose(a @ b, m, rtol=0, atol=1e-13)
        np.testing.assert_allclose(lower, np.tril(lower), atol=0)
        assert np.all(np.diag(lower) > 0)
        np.testing.assert_allclose(rot @ rot.T, np.eye(3), atol=1e-13)
        assert np.linalg.det(rot) == pytest.approx(1.0)


def test_a_reflection_is_refused():
    with pytest.raises(ValueError, match="positive determinant"):
        lower_times_rotation(np.diag([1.0, 1.0, -1.0]))


def _kalibr_check(imu0, calibration, raw):
    """Kalibr (IccScaledMisalignedImu): a_m = M_a a_i + b_a, w_m = M_g C_gyro_i w_i + A C_gyro_i
    a_i + b_g, so a_i = M_a^-1 (a_m - b_a), w_i = C_gyro_i^T M_g^-1 (w_m - b_g - A C_gyro_i
    a_i); frame B from v_B = R_i_B^T v_i."""
    r_i_b = np.array(imu0["imucal_R_i_B"])
    m_a = np.array(imu0["accelerometers"]["M"])
    a_i = np.linalg.solve(m_a, (raw["acc"] - imu0["imucal_acc_bias"]).T).T
    m_g, c = np.array(imu0["gyroscopes"]["M"]), np.array(imu0["gyroscopes"]["C_gyro_i"])
    a = np.array(imu0["gyroscopes"]["A"])
    w_m = raw["gyr"] - imu0["imucal_gyr_bias"] - a_i @ (a @ c).T
    w_i = (c.T @ np.linalg.solve(m_g, w_m.T)).T
    np.testing.assert_allclose(a_i @ r_i_b, _ours(calibration, "acc", raw["acc"]), atol=1e-9)
    np.testing.assert_allclose(w_i @ r_i_b, _ours(calibration, "gyr", raw["gyr"], raw["acc"]),
                               atol=1e-9)  # fmt: skip
    # the matrices Kalibr estimates are lower triangular (MatrixBasicDv pattern)
    for m in (m_a, m_g):
        np.testing.assert_array_equal(m, np.tril(m))
    assert imu0["model"] == "scale-misalignment"
    return a


def test_kalibr_equation_gives_our_calibration(files, calibration, raw):
    a = _kalibr_check(files["imucal-imu.yaml"]["imu0"], calibration, raw)
    np.testing.assert_array_equal(a, np.zeros((3, 3)))  # no g-sensitivity in the model


def _openvins_d(t):
    """Dw (or Da) as OpenVINS's 'kalibr' model keeps it: T^-1, lower triangle only
    (VioManagerOptions.h: vec_dw << Dw.block<3,1>(0,0), Dw.block<2,1>(1,1), Dw(2,2))."""
    return np.tril(np.linalg.inv(np.array(t)))


def test_openvins_equation_gives_our_calibration(files, calibration, raw):
    _openvins_check(files["kalibr_imu_chain.yaml"]["imu0"], calibration, raw)


@pytest.mark.parametrize(
    ("name", "check"),
    [
        ("imucal-imu.yaml", "_kalibr_check"),
        ("kalibr_imu_chain.yaml", "_openvins_check"),
    ],
)
def test_the_g_sensitivity_is_carried_and_the_terms_dropped_are_named(
    files_with_terms, with_terms, raw, name, check
):
    """Kalibr's A and OpenVINS's Tg carry our G (the tool's equation gives our rate with G a_B
    removed); the temperature term has no place and the header says so."""
    text = files_with_terms[name]
    g = globals()[check](yaml.safe_load(text)["imu0"], with_terms, raw)
    assert np.abs(g).max() > 1e-5
    assert "NOT in this file: the model terms temperature of calibration.json" in text


def test_the_ros_block_names_every_term(files_with_terms):
    ros = files_with_terms["imu_covariance.yaml"]
    assert "model terms temperature, g_sensitivity of calibration.json" in ros


def _openvins_check(imu0, calibration, raw):
    """OpenVINS (propagation-analytical.dox): w_I = R_IMUtoGYRO^T Dw (w_m - Tg a_I - b_g),
    a_I = R_IMUtoACC^T Da (a_m - b_a), with the lower triangle of Dw = Tw^-1 and Da = Ta^-1."""
    assert imu0["model"] == "kalibr"
    r_acc = np.array(imu0["R_IMUtoACC"]).T
    a_imu = (r_acc @ _openvins_d(imu0["Ta"]) @ (raw["acc"] - imu0["imucal_acc_bias"]).T).T
    r_gyr = np.array(imu0["R_IMUtoGYRO"]).T
    tg = np.array(imu0["Tg"])
    w_m = raw["gyr"] - imu0["imucal_gyr_bias"] - (tg @ a_imu.T).T
    w_imu = (r_gyr @ _openvins_d(imu0["Tw"]) @ w_m.T).T
    np.testing.assert_allclose(a_imu, _ours(calibration, "acc", raw["acc"]), atol=1e-9)
    np.testing.assert_allclose(w_imu, _ours(calibration, "gyr", raw["gyr"], raw["acc"]),
                               atol=1e-9)  # fmt: skip
    return tg


def test_ros_calibration_block_and_covariance(files, calibration, noise, raw):
    """The published sample is K (v_m - b); its covariance is K diag(N^2 f_s) K^T."""
    ros = files["imu_covariance.yaml"]
    for sensor, key in (("acc", "linear_acceleration_covariance"),
                        ("gyr", "angular_velocity_covariance")):  # fmt: skip
        block = ros["calibration"][sensor]
        applied = (np.array(block["matrix"]) @ (raw[sensor] - block["bias"]).T).T
        np.testing.assert_allclose(applied, _ours(calibration, sensor, raw[sensor]), atol=1e-9)
        k = np.array(calibration[sensor]["matrix"])
        dens = [noise["sensors"][sensor]["axes"][a]["terms"]["N"]["value"] for a in "xyz"]
        expected = k @ np.diag(np.square(dens) * noise["rate_hz"]) @ k.T
        cov = np.reshape(ros[key], (3, 3))
        np.testing.assert_allclose(cov, expected, rtol=1e-12)
        np.testing.assert_array_equal(cov, cov.T)
    assert ros["orientation_covariance"][0] == -1.0


def test_ros_covariance_matches_calibrated_white_noise(calibration, noise):
    """Sample covariance of calibrated raw white noise of the exported per-axis densities.

    Tolerance: the standard error of a sample covariance entry, sqrt((s_ii s_jj + s_ij^2) / n),
    times 5."""
    from imucal.export.model import inertial_calibration
    from imucal.export.ros import axis_densities, sample_covariance

    cal = inertial_calibration(calibration)["gyr"]
    dens = axis_densities(noise, "gyr")
    rng = np.random.default_rng(9)
    n = 200_000
    raw = dens * np.sqrt(noise["rate_hz"]) * rng.standard_normal((n, 3)) + cal.bias
    sample = np.cov(cal.apply(raw, "rad/s").T)
    expected = sample_covariance(cal, dens, noise["rate_hz"])
    d = np.diag(expected)
    se = np.sqrt((np.outer(d, d) + expected**2) / n)
    assert np.all(np.abs(sample - expected) < 5 * se)


def test_files_load_and_carry_the_keys_each_tool_reads(files):
    assert set(files["imu.yaml"]) == KALIBR_IMU_KEYS
    assert KALIBR_CHAIN_KEYS <= set(files["imucal-imu.yaml"]["imu0"])
    assert set(files["imucal-imu.yaml"]["imu0"]["gyroscopes"]) == {"M", "A", "C_gyro_i"}
    assert set(files["imucal-imu.yaml"]["imu0"]["accelerometers"]) == {"M"}
    assert OPENVINS_KEYS <= set(files["kalibr_imu_chain.yaml"]["imu0"])
    assert ROS_KEYS <= set(files["imu_covariance.yaml"])


def test_noise_values_round_trip(files, noise):
    """The Kalibr and OpenVINS noise values are the largest axis of noise.json, exactly."""
    expected = {}
    for sensor, prefix in (("acc", "accelerometer"), ("gyr", "gyroscope")):
        expected[f"{prefix}_noise_density"] = sensor_noise(noise, sensor, "N")[0]
        expected[f"{prefix}_random_walk"] = sensor_noise(noise, sensor, "K")[0]
    for name in ("imu.yaml",):
        for key, value in expected.items():
            assert files[name][key] == value
    for name in ("imucal-imu.yaml", "kalibr_imu_chain.yaml"):
        for key, value in expected.items():
            assert files[name]["imu0"][key] == value
        assert files[name]["imu0"]["update_rate"] == pytest.approx(noise["rate_hz"], rel=1e-6)


def test_files_state_the_inflation_and_how_each_value_was_obtained(calibration, noise):
    text = export_files("kalibr", calibration, noise)["imu.yaml"]
    assert "NOT inflated" in text and "10-20x" in text
    params = noise_parameters(noise)
    assert all(isinstance(v, bool) for v in params.resolved.values())
    assert "Allan fit" in text or "UPPER BOUND" in text


def test_openvins_file_starts_with_a_directive_opencv_and_pyyaml_read(calibration, noise):
    text = export_files("openvins", calibration, noise)["kalibr_imu_chain.yaml"]
    assert text.startswith("%YAML 1.0\n---\n")


#: What OpenVINS reads under imu0 of kalibr_imu_chain.yaml, through OpenCV's FileStorage
#: (ov_core/src/utils/opencv_yaml_parse.h): the noise values as double
#: (VioManagerOptions.h, print_and_load_noise), the model as string (StateOptions.h), the topic
#: as string (the ROS nodes' subscriber) and the five 3x3 matrices as a sequence of three rows
#: of three numbers (print_and_load_state; parse() of Eigen::Matrix3d reads file_node[r][c]).
OPENVINS_REALS = ("gyroscope_noise_density", "gyroscope_random_walk",
                  "accelerometer_noise_density", "accelerometer_random_walk")  # fmt: skip
OPENVINS_STRINGS = ("model", "rostopic")
OPENVINS_MATRICES = ("Tw", "Ta", "R_IMUtoACC", "R_IMUtoGYRO", "Tg")


def _opencv_imu0(path):
    """imu0 of a file as OpenVINS reads it: through cv2.FileStorage, node by node."""
    cv2 = pytest.importorskip("cv2", reason="OpenCV (opencv-python-headless, the test extra)")
    storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    assert storage.isOpened()
    imu0 = storage.getNode("imu0")
    assert imu0.isMap()
    out = {}
    for name in OPENVINS_REALS:
        node = imu0.getNode(name)
        assert node.isReal(), name
        out[name] = node.real()
    for name in OPENVINS_STRINGS:
        node = imu0.getNode(name)
        assert node.isString(), name
        out[name] = node.string()
    for name in OPENVINS_MATRICES:
        node = imu0.getNode(name)
        assert node.isSeq() and node.size() == 3, name
        rows = [node.at(r) for r in range(3)]
        assert all(row.isSeq() and row.size() == 3 for row in rows), name
        out[name] = [[row.at(c).real() for c in range(3)] for row in rows]
    for name in ("imucal_acc_bias", "imucal_gyr_bias"):  # ours, for the check below
        node = imu0.getNode(name)
        out[name] = [node.at(i).real() for i in range(3)]
    storage.release()
    return out


@pytest.mark.parametrize("terms", [False, True])
def test_openvins_reads_the_file_with_opencv(tmp_path, calibration, with_terms, noise, raw,
                                            terms):  # fmt: skip
    """OpenCV's FileStorage opens the file and every node OpenVINS reads has its type and
    shape; OpenVINS's equation on the numbers OpenCV read gives our calibrated samples."""
    cal = with_terms if terms else calibration
    path = tmp_path / "kalibr_imu_chain.yaml"
    path.write_text(export_files("openvins", cal, noise)["kalibr_imu_chain.yaml"])
    imu0 = _opencv_imu0(path)
    assert imu0["model"] == "kalibr" and imu0["rostopic"] == "/imu0"
    expected = yaml.safe_load(path.read_text())["imu0"]
    for name in OPENVINS_REALS:
        assert imu0[name] == expected[name]
    tg = _openvins_check(imu0, cal, raw)
    assert (np.abs(tg).max() > 1e-5) == terms


def test_kalibr_reads_the_imu_file_as_its_config_reader_does(tmp_path, calibration, noise):
    """Kalibr's ImuParameters (kalibr_common/ConfigReader.py): yaml.safe_load, rostopic a str,
    update_rate > 0, each density and random walk > 0; the discrete-time sigma it derives is
    density / sqrt(1 / update_rate)."""
    (tmp_path / "imu.yaml").write_text(export_files("kalibr", calibration, noise)["imu.yaml"])
    with open(tmp_path / "imu.yaml") as f:
        data = yaml.safe_load(f)
    assert isinstance(data["rostopic"], str)
    assert isinstance(data["update_rate"], float) and data["update_rate"] > 0.0
    for prefix in ("accelerometer", "gyroscope"):
        density, walk = data[f"{prefix}_noise_density"], data[f"{prefix}_random_walk"]
        assert isinstance(density, float) and density > 0.0
        assert isinstance(walk, float) and walk > 0.0
    sensor = noise["sensors"]["gyr"]["axes"]
    largest = max(sensor[a]["terms"]["N"]["value"] for a in "xyz")
    discrete = data["gyroscope_noise_density"] / np.sqrt(1.0 / data["update_rate"])
    assert discrete == pytest.approx(largest * np.sqrt(RATE), rel=1e-9)


def test_the_kalibr_results_file_has_kalibrs_imu_set_layout(files):
    """Kalibr's ImuSetParameters writes one entry per IMU, imu0, imu1, ...; the entry holds the
    ImuParameters keys and the model's matrices, each 3x3 of floats."""
    data = files["imucal-imu.yaml"]
    assert list(data) == ["imu0"]
    imu0 = data["imu0"]
    for block, names in (("accelerometers", ("M",)), ("gyroscopes", ("M", "A", "C_gyro_i"))):
        for name in names:
            m = np.asarray(imu0[block][name], dtype=np.float64)
            assert m.shape == (3, 3)
    assert np.asarray(imu0["T_i_b"], dtype=np.float64).shape == (4, 4)


def test_ros_file_has_the_message_layout(files):
    """sensor_msgs/Imu: each covariance float64[9], row major, symmetric and positive
    definite for the rates and accelerations; -1 in element 0 of the orientation's."""
    ros = files["imu_covariance.yaml"]
    for key in ROS_KEYS:
        assert len(ros[key]) == 9 and all(isinstance(v, float) for v in ros[key])
    assert ros["orientation_covariance"] == [-1.0] + [0.0] * 8
    for key in ("angular_velocity_covariance", "linear_acceleration_covariance"):
        cov = np.reshape(ros[key], (3, 3))
        np.testing.assert_array_equal(cov, cov.T)
        assert np.all(np.linalg.eigvalsh(cov) > 0)


def test_the_rate_is_written_rounded(calibration, noise):
    """The rate from the median time step (100.00000000000213 Hz) is written as 100.0."""
    rough = {**noise, "rate_hz": 100.00000000000213}
    for fmt in FORMATS:
        for name, text in export_files(fmt, calibration, rough).items():
            if "update_rate" in text:
                assert "update_rate: 100.0\n" in text, name


def test_a_partial_calibration_without_accelerometer_is_refused(calibration, noise):
    partial = {"format_version": 1, "gyr": calibration["gyr"]}
    with pytest.raises(ValueError, match=r"lacks \['acc'\]"):
        export_files("kalibr", partial, noise)
    with pytest.raises(ValueError, match="unknown export format"):
        export_files("vins", calibration, noise)


def test_cli_writes_every_format(tmp_path, calibration, noise, capsys):
    cal_path, noise_path = tmp_path / "calibration.json", tmp_path / "noise.json"
    cal_path.write_text(json.dumps(calibration))
    noise_path.write_text(json.dumps(noise))
    for fmt, names in FORMATS.items():
        out = tmp_path / fmt
        assert (
            main(["export", "--format", fmt, str(cal_path), str(noise_path), "-o", str(out)]) == 0
        )
        for name in names:
            assert yaml.safe_load((out / name).read_text()) == yaml.safe_load(
                export_files(fmt, calibration, noise)[name]
            )
    (tmp_path / "partial.json").write_text(json.dumps({"format_version": 1}))
    assert main(["export", "--format", "ros", str(tmp_path / "partial.json"), str(noise_path)]) == 2
    assert "lacks ['acc', 'gyr']" in capsys.readouterr().err


def test_a_stage_that_did_not_run_writes_yaml_records(tmp_path):
    from imucal.pipeline.outcome import not_run_reason, write_not_run

    path = tmp_path / "export" / "imu.yaml"
    write_not_run("export", "no static recording", {"kalibr_imu": path})
    assert not_run_reason(yaml.safe_load(path.read_text())) == (
        "export did not run: no static recording"
    )
