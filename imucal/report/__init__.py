"""The HTML lab report (``lab``, jinja2 templates in ``templates/``).

``lab`` assembles the report's context and renders it; ``sections`` builds the sections' contents,
``figures`` embeds and captions the figures, ``artifacts`` reads the artifacts and benchmarks and
``fields`` renders nested JSON.
"""

from imucal.report.artifacts import read_benchmarks
from imucal.report.fields import collect_warnings, flatten_fields
from imucal.report.figures import (
    DEFAULT_CAPTIONS,
    FIGURE_SECTION_BY_PREFIX,
    embed_figure,
    figure_section,
)
from imucal.report.lab import SECTION_TITLES, SENSOR_SECTIONS, build_report_context, render_report
from imucal.report.numbers import DIGITS, MAX_LISTED_VALUES, format_number, format_value
from imucal.report.sections import PARAMETER_NAMES, PARAMETER_UNITS, RATE_TABLE, TABLE_TITLES

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
