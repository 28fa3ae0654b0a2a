"""One identification per unit: the explanation (TG Type I and the effect catalogue) and
the deliverable (each standard record's calibration and fidelity, the recommended one),
from one selection with one noise model. See :mod:`.workflow`."""

from .result import Identification, StandardRecord, TestFidelity
from .unit import Unit
from .workflow import identify

__all__ = ["Identification", "StandardRecord", "TestFidelity", "Unit", "identify"]
