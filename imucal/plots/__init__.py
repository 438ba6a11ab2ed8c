"""Figures of the pipeline; every function returns a ``matplotlib.figure.Figure`` and never saves
or shows it."""
