"""The HTML lab report (``lab``, jinja2 templates in ``templates/``)."""

from imucal.report.lab import (
    DEFAULT_CAPTIONS,
    FIGURE_SECTION_BY_PREFIX,
    PARAMETER_NAMES,
    PARAMETER_UNITS,
    RATE_TABLE,
    SECTION_TITLES,
    SENSOR_SECTIONS,
    TABLE_TITLES,
    build_report_context,
    collect_warnings,
    embed_figure,
    figure_section,
    flatten_fields,
    read_benchmarks,
    render_report,
)
from imucal.report.numbers import DIGITS, MAX_LISTED_VALUES, format_number, format_value

__all__ = [
    "DEFAULT_CAPTIONS",
    "DIGITS",
    "FIGURE_SECTION_BY_PREFIX",
    "MAX_LISTED_VALUES",
    "PARAMETER_NAMES",
    "PARAMETER_UNITS",
    "RATE_TABLE",
    "SECTION_TITLES",
    "SENSOR_SECTIONS",
    "TABLE_TITLES",
    "build_report_context",
    "collect_warnings",
    "embed_figure",
    "figure_section",
    "flatten_fields",
    "format_number",
    "format_value",
    "read_benchmarks",
    "render_report",
]
