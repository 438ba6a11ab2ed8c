"""The text of each export file: YAML with a comment header (what, from where, what to inflate)."""

from __future__ import annotations

from collections.abc import Mapping

import yaml

from imucal.export.formats import FORMATS
from imucal.export.kalibr import kalibr_imu, kalibr_imu_chain, noise_header
from imucal.export.model import (
    ROSTOPIC,
    g_sensitivity,
    inertial_calibration,
    noise_parameters,
    terms_not_written,
)
from imucal.export.openvins import DIRECTIVE, openvins_imu_chain
from imucal.export.ros import ros_imu_covariances


class _Dumper(yaml.SafeDumper):
    """Block mappings as in the tools' own files; rows of numbers as flow lists ``[a, b, c]``;
    the items of a block list indented under their key, as OpenCV's YAML reader requires
    (``- [...]`` at the key's own indentation is "Incorrect indentation" there)."""

    def increase_indent(self, flow: bool = False, indentless: bool = False) -> None:
        return super().increase_indent(flow, False)


def _represent_list(dumper: yaml.SafeDumper, data: list) -> yaml.Node:
    flat = all(not isinstance(v, (list, dict)) for v in data)
    return dumper.represent_sequence("tag:yaml.org,2002:seq", data, flow_style=flat)


_Dumper.add_representer(list, _represent_list)


def _yaml(data: Mapping, header: list[str], directive: str = "") -> str:
    comments = "".join(f"# {line}\n" if line else "#\n" for line in header)
    body = yaml.dump(dict(data), Dumper=_Dumper, sort_keys=False, default_flow_style=False,
                     width=200)  # fmt: skip
    return directive + comments + body


def export_files(
    fmt: str, calibration: Mapping, noise: Mapping, *, rostopic: str = ROSTOPIC
) -> dict[str, str]:
    """File name -> text of one export format.

    Parameters
    ----------
    fmt : str
        One of :data:`FORMATS`.
    calibration : mapping
        calibration.json content (full or partial; accelerometer and gyroscope needed).
    noise : mapping
        noise.json content (:func:`imucal.noise.characterise_noise`).
    rostopic : str
        IMU topic written in the Kalibr and OpenVINS files.

    Raises
    ------
    ValueError
        For an unknown format, a calibration without accelerometer or gyroscope, or a noise
        analysis without them.
    """
    if fmt not in FORMATS:
        raise ValueError(f"unknown export format {fmt!r}; expected one of {sorted(FORMATS)}")
    cal = inertial_calibration(calibration)
    source = "Calibration and noise by imucal (docs/exports.md: conventions and sources)."
    if fmt == "ros":
        head = [source, "sensor_msgs/Imu covariances of one calibrated sample, row major x, y, z;",
                "(rad/s)^2 and (m/s^2)^2; per-sample white noise only, NOT inflated.",
                *terms_not_written(calibration, "ros")]  # fmt: skip
        return {FORMATS["ros"][0]: _yaml(ros_imu_covariances(cal, noise), head)}
    params = noise_parameters(noise)
    g = g_sensitivity(calibration)
    if fmt == "kalibr":
        imu, chain = FORMATS["kalibr"]
        chain_head = [source, "Kalibr scale-misalignment model: a_m = M_a a_i + b_a,",
                      "w_m = M_g C_gyro_i w_i + A C_gyro_i a_i + b_g; v_i = imucal_R_i_B v_B.",
                      *terms_not_written(calibration, "kalibr"),
                      *noise_header(params)]  # fmt: skip
        return {
            imu: _yaml(kalibr_imu(params, rostopic=rostopic), [source, *noise_header(params)]),
            chain: _yaml(
                kalibr_imu_chain(cal, params, g_sensitivity=g, rostopic=rostopic), chain_head
            ),
        }
    head = [source, "OpenVINS model 'kalibr': w_I = R_IMUtoGYRO^T Tw^-1 (w_m - Tg a_I - b_g),",
            "a_I = R_IMUtoACC^T Ta^-1 (a_m - b_a); frame I is imucal's platform frame B.",
            *terms_not_written(calibration, "openvins"),
            *noise_header(params)]  # fmt: skip
    return {FORMATS["openvins"][0]: _yaml(openvins_imu_chain(cal, params, g_sensitivity=g,
                                                              rostopic=rostopic),
                                           head, DIRECTIVE)}  # fmt: skip
