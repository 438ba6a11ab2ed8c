"""The rules' logs: one format, Python warnings captured, warnings read back with counts."""

import subprocess
import sys
from pathlib import Path

import pytest

from imucal.io.logs import LoggedWarning, read_log_warnings

REPO = Path(__file__).resolve().parents[2]


def test_a_rule_log_holds_logged_and_python_warnings(tmp_path):
    log = tmp_path / "rule.log"
    script = (
        "import logging, warnings\n"
        "from imucal.io.logs import log_to\n"
        f"log_to({str(log)!r})\n"
        "logging.getLogger('imucal.segments.filtering').warning('mag: cutoff 5 Hz is not below')\n"
        "logging.getLogger('imucal.segments.filtering').warning('mag: cutoff 5 Hz is not below')\n"
        "logging.info('fitted')\n"
        "warnings.warn('mean of empty slice', RuntimeWarning)\n"
    )
    subprocess.run([sys.executable, "-c", script], check=True, cwd=REPO,
                   env={"PYTHONPATH": str(REPO), "PATH": ""})  # fmt: skip
    found = read_log_warnings(log)
    assert found[0] == LoggedWarning(
        "WARNING", "imucal.segments.filtering", "mag: cutoff 5 Hz is not below", 2
    )
    assert len(found) == 2  # the INFO record is not a warning
    python = found[1]
    assert python.logger == "py.warnings" and python.count == 1
    assert "RuntimeWarning: mean of empty slice" in python.text


def test_continuation_lines_and_levels(tmp_path):
    log = tmp_path / "rule.log"
    log.write_text(
        "INFO:root:start\nERROR:imucal.x:it failed\nTraceback (most recent call last):\n"
        '  File "x.py", line 1\nWARNING:imucal.y:a\nWARNING:imucal.y:a\nDEBUG:imucal.y:z\n'
    )
    assert read_log_warnings(log) == [
        LoggedWarning("ERROR", "imucal.x", 'it failed\nTraceback (most recent call last):\n'
                      '  File "x.py", line 1', 1),
        LoggedWarning("WARNING", "imucal.y", "a", 2),
    ]  # fmt: skip
    with pytest.raises(FileNotFoundError, match="missing.log: log file not found"):
        read_log_warnings(tmp_path / "missing.log")
