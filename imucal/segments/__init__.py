"""Segments of the recordings: the low-pass filter (``filtering``), the static detector
(``detector``), the protocol segmenters (``protocol``, ``ratetable``), the hand-held holds
(``holds``), the segments table (``table``) and the dataset's segmentation (``segmentation``).
"""
