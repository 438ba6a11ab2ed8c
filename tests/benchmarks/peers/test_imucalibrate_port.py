"""The IMUcalibrate port reproduces scikit-diveMove's own models of its CATS recording.

``results.json`` holds what the peer's own ``build_tmodels`` (its 0.4.0 wheel, run by
``run_peers.py`` in its venv) fitted: 30 models, without and with a break temperature. The
port must give the same coefficients and standard errors to round-off, and the package's
IMUcalibrate model of the temperature hold-out the port's slope.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import imucalibrate_check  # noqa: E402

CATS = HERE.parents[3] / "shared" / "data" / "real" / "spluque__scikit-diveMove"
CATS_FILE = CATS / "cats_temperature_calib.nc"


@pytest.fixture(scope="module")
def periods():
    if not CATS_FILE.is_file():
        pytest.skip(f"the CATS recording is not at {CATS_FILE} (../shared is absent)")
    return imucalibrate_check.load_cats(CATS_FILE)


def peer_models() -> list[dict]:
    results = json.loads((HERE / "results.json").read_text())
    return results["imucalibrate"]["peer"]["models"]


def test_the_port_gives_the_peers_own_coefficients(periods):
    peer = peer_models()
    assert len(peer) == 30  # 3 + 9 + 3 models (its test's calls), without and with T_brk
    port = imucalibrate_check.port_models(periods, None) + imucalibrate_check.port_models(
        periods, 10.0
    )
    worst = imucalibrate_check.compare(peer, port)["max_relative_difference"]
    # float64 round-off of the same least-squares solution: far below any fit's std
    assert worst["params"] < 1e-9
    assert worst["bse"] < 1e-9
    assert worst["at_t_alpha"] < 1e-12
    # the figures the peer's docs and test do give: its periods' sizes and three models each
    assert {(m["period"], m["nobs"]) for m in peer} == {(0, 91981), (1, 90901), (2, 83101)}


def test_a_wrong_port_is_caught(periods):
    """Without the peer's Savitzky-Golay smoothing the slopes move by more than round-off."""
    from imucalibrate_port import build_tmodels

    peer = {(m["var"], m["period"], m["axis"]): m for m in peer_models() if m["t_brk"] is None}
    raw = build_tmodels(periods["angular_velocity"], filter_sig=False)
    moved = max(
        abs(raw[p][j].params[1] / peer[("angular_velocity", p, "xyz"[j])]["params"][1] - 1)
        for p in range(3)
        for j in range(3)
    )
    assert moved > 1e-6


def test_the_hold_outs_imucalibrate_model_is_the_ports(periods):
    from imucalibrate_port import build_tmodels

    from imucal.terms.thermalpeers import per_period_line, smoothed

    temp, values = periods["angular_velocity"][1]
    port = build_tmodels([(temp, values)])[0]
    labels = np.zeros(len(temp), int)
    for j in range(3):
        line = per_period_line(temp, smoothed(values)[:, j], labels, 1)
        assert line.coef[0] == pytest.approx(port[j].params[1], rel=1e-10)
