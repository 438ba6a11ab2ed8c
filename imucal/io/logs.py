"""The rules' log files: one format for every rule script, and the warnings read back from them.

A rule script logs to its Snakemake log with :func:`log_to`: Python's ``logging`` in
:data:`LOG_FORMAT`, with the warnings of the ``warnings`` module (NumPy's, SciPy's) captured
into the same file. :func:`read_log_warnings` reads back every record at level WARNING or above,
so that the lab report lists what each rule warned about.
"""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass
from pathlib import Path

#: Format of every rule's log: ``LEVEL:logger:message`` (``logging``'s default).
LOG_FORMAT = "%(levelname)s:%(name)s:%(message)s"
#: Levels read back as warnings.
WARNING_LEVELS = ("WARNING", "ERROR", "CRITICAL")
_RECORD = re.compile(r"^(DEBUG|INFO|WARNING|ERROR|CRITICAL):([^:]*):(.*)$")


def log_to(path: str | Path) -> None:
    """Send this process's log records (INFO and above) and Python warnings to ``path``
    (overwritten) in :data:`LOG_FORMAT`."""
    logging.basicConfig(filename=str(path), filemode="w", level=logging.INFO, format=LOG_FORMAT)
    logging.captureWarnings(True)


@dataclass(frozen=True)
class LoggedWarning:
    """A warning of a rule's log.

    Attributes
    ----------
    level : str
        ``WARNING``, ``ERROR`` or ``CRITICAL``.
    logger : str
        The logger that wrote it (the module, or ``py.warnings`` for a Python warning).
    text : str
        The message, its continuation lines joined by newlines.
    count : int
        How many times the log holds this message (repeats are counted, not listed).
    """

    level: str
    logger: str
    text: str
    count: int


def read_log_warnings(path: str | Path) -> list[LoggedWarning]:
    """The warnings of a log written in :data:`LOG_FORMAT`, repeats counted, in the order they
    first appear.

    Raises
    ------
    FileNotFoundError
        If the log does not exist.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: log file not found; expected the log of a rule")
    records: list[list[str]] = []
    for line in path.read_text(encoding="utf-8", errors="replace").splitlines():
        match = _RECORD.match(line)
        if match:
            records.append([match[1], match[2], match[3]])
        elif records and line.strip():  # a continuation line (a traceback, a warning's source)
            records[-1][2] += "\n" + line
    counts: dict[tuple[str, str, str], int] = {}
    for level, logger, text in records:
        if level in WARNING_LEVELS:
            key = (level, logger, text.strip())
            counts[key] = counts.get(key, 0) + 1
    return [LoggedWarning(*key, count) for key, count in counts.items()]
