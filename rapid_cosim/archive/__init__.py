"""The archive of a run: one HDF5 file, written once per iteration, read, re-run, resumed."""

from .store import (
    FORMAT_VERSION,
    ArchiveWriter,
    RunArchive,
    StoredEvaluations,
    data_sha256,
)

__all__ = ["FORMAT_VERSION", "ArchiveWriter", "RunArchive", "StoredEvaluations", "data_sha256"]
