"""Segments of the recordings: the low-pass filter (``filtering``), the static detector and the
protocol segmenters (``segmentation``), the hand-held holds detector (``holds``).
"""
