"""Run magcal (PyPI) on magnetometer samples; executed by the magcal peers venv.

Usage: ``<venv>/bin/python magcal_adapter.py <samples.json> <out.json>`` with the samples a
JSON list of ``[x, y, z]`` (the format of the files ``magcal from-file`` reads). Writes the
centre and transform ``calibrate("ellipsoid")`` fits (``calibrated = transform @ (m -
centre)``, as its C header states), its quality figures, or ``refused`` with its message.
"""

import importlib.metadata
import json
import sys
from pathlib import Path

from magcal.core import MagnetometerCalibrator


def main() -> None:
    samples, out = sys.argv[1:3]
    cal = MagnetometerCalibrator()
    cal.load_data_from_file(samples)
    try:
        params = cal.calibrate(method="ellipsoid")
    except Exception as err:  # the peer raises a bare Exception below 500 samples
        Path(out).write_text(json.dumps({"refused": f"magcal: {err}"}))
        return
    result = {
        "version": importlib.metadata.version("magcal"),
        "center": params["center"].tolist(),
        "transform_matrix": params["transform_matrix"].tolist(),
        "quality": {k: float(v) for k, v in cal.calibration_quality.items()},
    }
    Path(out).write_text(json.dumps(result))


if __name__ == "__main__":
    main()
