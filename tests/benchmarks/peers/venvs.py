"""The peers' virtual environments: each peer installed from PyPI as it ships, apart from ours.

One venv per peer under ``.cache/`` (their dependencies differ, and mad-lab-fau's ``imucal``
has our import name). scikit-diveMove is installed without its dependencies on R (``rpy2``
and R's diveMove, which cannot be installed here): its wheel and the packages its
temperature models import.
"""

from __future__ import annotations

import os
import subprocess
import sys
import venv
from pathlib import Path

#: Peer -> (pip requirement lines, a check that imports what the adapter needs). Versions of
#: the peers are pinned; their dependencies are what pip resolves (recorded in results.json).
PEERS = {
    "imucal": ([["imucal==2.6.0"]], "import imucal.ferraris_calibration"),
    "magcal": ([["magcal==1.0.1"]], "import magcal.core"),
    "skdivemove": (
        [
            ["--no-deps", "scikit-diveMove==0.4.0"],
            ["numpy", "pandas", "scipy", "xarray", "statsmodels", "h5netcdf", "h5py", "matplotlib",
             "allantools", "ahrs", "scikit-learn"],
        ],
        "import h5py, statsmodels, xarray, importlib.util; assert importlib.util.find_spec('skdiveMove')",
    ),
}  # fmt: skip


def peer_env() -> dict:
    """Environment for a venv's python: without PYTHONPATH (which would put our ``imucal``
    ahead of the peer) and with a display-free matplotlib (magcal imports pyplot)."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["MPLBACKEND"] = "Agg"
    return env


def ensure(name: str, root: Path) -> Path:
    """The python of peer ``name``'s venv, created and installed when missing or broken.

    Exits with status 0 and ``SKIPPED`` when pip cannot install it (no network)."""
    requirements, check = PEERS[name]
    where = root / ".cache" / ("peers-venv" if name == "imucal" else f"peers-venv-{name}")
    python = where / "bin" / "python"
    probe = [str(python), "-c", check]
    if (
        python.exists()
        and subprocess.run(probe, capture_output=True, env=peer_env()).returncode == 0
    ):
        return python
    venv.create(where, with_pip=True, clear=True)
    for line in requirements:
        pip = subprocess.run([str(python), "-m", "pip", "install", "--quiet", *line],
                             capture_output=True, text=True, env=peer_env())  # fmt: skip
        if pip.returncode != 0:
            print(f"SKIPPED: pip could not install {line} into {where} (no network?):\n"
                  f"{pip.stderr[-800:]}")  # fmt: skip
            sys.exit(0)
    return python


def versions(python: Path, packages: list[str]) -> dict:
    """The installed version of each of ``packages`` in a venv."""
    code = ("import importlib.metadata as m, json; print(json.dumps({p: m.version(p) for p in "
            + repr(list(packages)) + "}))")  # fmt: skip
    out = subprocess.run([str(python), "-c", code], capture_output=True, text=True, check=True,
                         env=peer_env())  # fmt: skip
    return __import__("json").loads(out.stdout)
