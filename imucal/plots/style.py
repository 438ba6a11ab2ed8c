"""The sizes every figure of the report is drawn at, defined once.

The lab report shows a figure at most :data:`PAGE_WIDTH_PX` wide (its text column at 1280 px;
``report.html.j2``), scaled down when the file is wider. A figure drawn at most
:data:`PAGE_WIDTH_IN` wide and saved at :data:`FIGURE_DPI` is shown unscaled, so that a text of
:data:`MIN_FONT_PT` is :data:`MIN_TEXT_PX` or more on the screen
(``MIN_FONT_PT / 72 * FIGURE_DPI``); :mod:`imucal.plots.figurefile` records the texts of a
saved figure so that a check can measure them where the figure is shown.
"""

#: Resolution of every saved figure (dots per inch).
FIGURE_DPI = 110
#: Width of the report's text column (CSS px): ``max-width: 68rem`` at 16 px, less the
#: figure's 1 px border on each side.
PAGE_WIDTH_PX = 68 * 16 - 2
#: Widest figure shown unscaled at :data:`FIGURE_DPI` (inches).
PAGE_WIDTH_IN = round(PAGE_WIDTH_PX / FIGURE_DPI, 2)
#: Smallest text a reader is asked to read (CSS px, as rendered).
MIN_TEXT_PX = 10.0
#: Smallest font size of any text in a figure (pt): MIN_TEXT_PX at FIGURE_DPI, unscaled.
MIN_FONT_PT = 7.0
