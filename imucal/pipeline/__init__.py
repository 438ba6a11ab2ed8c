"""The chain of stages: one function per stage (``stages``), the partial path (``partial``) and
the record of a stage the data do not allow (``outcome``).
"""
