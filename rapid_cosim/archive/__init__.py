"""The archive of a run: one HDF5 file per run, enough to re-run or resume it alone.

``format`` (layout, encodings, crash-safe writes), ``lock`` (one writer per archive),
``writer`` (appending iterations, finishing) and ``reader`` (a view of a live or
finished archive): storage only; running estimations is :mod:`rapid_cosim.calibration`'s.
"""

from .format import FORMAT_VERSION, RunStatus, data_sha256
from .reader import RunArchive, StoredEvaluations
from .writer import ArchiveWriter

__all__ = ["FORMAT_VERSION", "ArchiveWriter", "RunArchive", "RunStatus", "StoredEvaluations", "data_sha256"]
