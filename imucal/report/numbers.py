"""How the report prints numbers: significant digits, vectors and matrices in table cells."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

#: Significant digits of the numbers in the report.
DIGITS = 5
#: Significant digits of the numbers in the report.
#: Lists longer than this are summarised (count, min, max) instead of printed in full.
MAX_LISTED_VALUES = 12


def format_number(value: Any, digits: int = DIGITS) -> str:
    """Format one number for the report.

    Parameters
    ----------
    value : int, float, bool or None
        The number. Integers are printed in full; floats with ``digits`` significant digits
        (trailing zeros dropped, scientific notation below 1e-4 and from 10**digits on where
        the value is not an integer).
    digits : int
        Significant digits of a float.

    Returns
    -------
    str
        ``'n/a'`` for None or NaN, ``'yes'``/``'no'`` for a bool.
    """
    if value is None:
        return "n/a"
    if isinstance(value, (bool, np.bool_)):
        return "yes" if value else "no"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    x = float(value)
    if math.isnan(x):
        return "n/a"
    if math.isinf(x):
        return "∞" if x > 0 else "-∞"
    if x == 0:
        return "0"
    if abs(x) >= 10**digits and x == round(x) and abs(x) < 1e15:
        return str(int(x))
    return f"{x:.{digits}g}"


def format_value(value: Any, digits: int = DIGITS) -> str:
    """Format a scalar, vector or matrix of numbers (or a string) for a table cell.

    Vectors print as ``[a, b, c]``, matrices row by row ``[[...], [...]]``; lists longer than
    :data:`MAX_LISTED_VALUES` as ``n values, min ... max``.
    """
    if isinstance(value, str):
        return value
    if isinstance(value, (list, tuple, np.ndarray)):
        flat = _numbers(value)
        if flat is not None and flat.size > MAX_LISTED_VALUES:
            finite = flat[np.isfinite(flat)]
            if finite.size == 0:
                return f"{flat.size} values, none finite"
            return (
                f"{flat.size} values, {format_number(finite.min(), digits)} ... "
                f"{format_number(finite.max(), digits)}"
            )
        return "[" + ", ".join(format_value(v, digits) for v in value) + "]"
    if value is None or isinstance(value, (bool, int, float, np.number, np.bool_)):
        return format_number(value, digits)
    return str(value)


def _numbers(value: Any) -> np.ndarray | None:
    """The values of a (nested) list of numbers as a flat float array, or None."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return None
    return arr.ravel() if arr.dtype.kind == "f" else None
