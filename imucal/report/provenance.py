"""Where a report came from: the commit of the workflow checkout that made it."""

from __future__ import annotations

import subprocess
from pathlib import Path


def workflow_commit(directory: str | Path) -> str:
    """The git commit checked out at ``directory``, or ``"unknown"`` outside a git checkout.

    Parameters
    ----------
    directory : str or Path
        A folder of the workflow (e.g. its scripts' folder).

    Returns
    -------
    str
        ``git rev-parse HEAD`` there (40 hex digits), or ``"unknown"`` when git is missing or
        the folder is not in a checkout (an installed copy, an exported tarball).
    """
    try:
        out = subprocess.run(
            ["git", "-C", str(directory), "rev-parse", "HEAD"],
            capture_output=True,
            text=True,
            check=True,
        )
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return out.stdout.strip()
