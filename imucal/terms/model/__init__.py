"""The model terms, one module each (:class:`imucal.terms.term.ModelTerm`); registered in
:mod:`imucal.terms.registry`."""
