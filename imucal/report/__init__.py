"""The HTML lab report (``lab``, jinja2 templates in ``templates/``).

``inputs`` holds what the report is built from and loads what its sections share; ``lab`` lays
it out with one builder per section and renders it; ``sections`` builds further sections'
contents, ``figures`` embeds and captions the figures, ``artifacts`` reads the artifacts and
benchmarks and ``fields`` renders nested JSON.
"""

from imucal.report.artifacts import read_benchmarks
from imucal.report.fields import collect_warnings, flatten_fields
from imucal.report.figures import (
    DEFAULT_CAPTIONS,
    FIGURE_SECTION_BY_PREFIX,
    embed_figure,
    figure_section,
)
from imucal.report.inputs import SECTION_TITLES, SENSOR_SECTIONS, ReportInputs, load_report
from imucal.report.lab import build_report_context, render_report
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
    "ReportInputs",
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
    "load_report",
    "read_benchmarks",
    "render_report",
]
