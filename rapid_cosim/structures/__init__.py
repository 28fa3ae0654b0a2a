"""Which governor structure fits a unit: ``structure`` (a structure file, read and
checked), ``select`` (each structure calibrated and
ranked by the criterion, ties and the recommendation, the effect catalogue run on the
winner) and ``identifiability`` (the Fisher information at an optimum: what the tests
determine, trade-offs, the step that would pin a parameter down). Used by ``identify``
and ``fleet``; it runs ``diagnose`` for the effects on a structure, never the reverse."""
