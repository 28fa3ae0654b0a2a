"""Typed errors, so that callers (the CLI, the parallel evaluator) can tell a user's
mistake from a failed simulation without parsing messages."""

from __future__ import annotations

from dataclasses import dataclass


class RapidCosimError(Exception):
    """Base of every error the toolkit raises on purpose."""


class ModelicaError(RapidCosimError):
    """A problem in Modelica source, located by file and line where it is known."""

    def __init__(self, message: str, file: str | None = None, line: int | None = None):
        self.file, self.line, self.detail = file, line, message
        where = f"{file}:{line}: " if file and line else (f"{file}: " if file else "")
        super().__init__(where + message)


class ModelicaSyntaxError(ModelicaError):
    """The parser rejected the source."""


class UnsupportedConstruct(ModelicaError):
    """Valid Modelica that the embedded compiler cannot translate."""


class BuildError(RapidCosimError):
    """A backend failed to produce an FMU (compiler output is in the message)."""


class ParameterError(RapidCosimError):
    """An unknown parameter name, or a value outside its declared range."""


class FmuError(RapidCosimError):
    """An FMU this toolkit cannot simulate (wrong FMI version or interface, no binary for
    this platform, a variable it cannot drive), with the reason."""


class SimulationError(RapidCosimError):
    """The solver failed for one parameter set; the caller decides what it costs."""


class SimulationTimeout(SimulationError):
    """A simulation exceeded its wall-time budget."""


class ConfigError(RapidCosimError):
    """A bad experiment configuration, located by file and key."""

    def __init__(self, message: str, file: str | None = None, key: str | None = None):
        self.file, self.key, self.detail = file, key, message
        where = f"{file}" if file else ""
        if key:
            where += f" [{key}]"
        super().__init__(f"{where}: {message}" if where else message)


class DataError(RapidCosimError):
    """Bad measurement data, located by file and (1-based, header = row 1) row."""

    def __init__(self, message: str, file: str | None = None, row: int | None = None):
        self.file, self.row, self.detail = file, row, message
        where = f"{file}" + (f", row {row}" if row is not None else "") if file else ""
        super().__init__(f"{where}: {message}" if where else message)


class ArchiveError(RapidCosimError):
    """An archive that is unreadable, inconsistent with a replay, or held by another run."""


class ArchiveDamaged(ArchiveError):
    """A part of an archive fails its checksum or cannot be read: which part, why, and
    what can still be read."""

    def __init__(self, path: str, part: str, reason: str, readable: str | None = None):
        self.path, self.part, self.reason, self.readable = path, part, reason, readable
        tail = f"; {readable}" if readable else ""
        super().__init__(f"{path}: damaged {part} ({reason}){tail}; 'rapid-cosim verify {path}' lists what is intact")


class ArchiveFull(ArchiveError):
    """The device holding an archive ran out of space; what was committed is kept."""


class EngineLost(RapidCosimError):
    """The cluster a run used is gone (its dask scheduler died or became unreachable)."""


class RunInterrupted(RapidCosimError):
    """A run stopped by Ctrl-C or SIGTERM; its archive is closed and can be resumed."""

    def __init__(self, archive: str, n_iterations: int):
        self.archive, self.n_iterations = archive, n_iterations
        super().__init__(f"interrupted; {archive} holds {n_iterations} complete iterations: "
                         f"'rapid-cosim resume {archive}' continues the run")


class ArchiveLocked(ArchiveError):
    """Another live process holds the archive for writing."""


class RecordError(RapidCosimError):
    """A grid simulator's record (PSS/E ``.dyr``, PSLF ``.dyd``) this toolkit cannot read
    as an iGrGen model: located by file and line, naming the field, its value and what is
    allowed."""

    def __init__(self, message: str, file: str | None = None, line: int | None = None,
                 field: str | None = None, value: object = None, allowed: str | None = None):
        self.file, self.line, self.field, self.value, self.allowed, self.detail = \
            file, line, field, value, allowed, message
        where = f"{file}:{line}" if file and line else (file or "")
        what = f"field {field} = {value!r}: " if field is not None else ""
        tail = f" (allowed: {allowed})" if allowed else ""
        super().__init__(f"{where}: {what}{message}{tail}" if where else f"{what}{message}{tail}")


class DeliveryError(RapidCosimError):
    """A record that, read back as a grid simulator reads it, does not simulate what the
    fit it was written from simulates: it is not handed over."""


@dataclass(frozen=True)
class Finding:
    """One thing wrong with a run's inputs, located where the user fixes it: the file, and
    its key, row or line."""

    file: str | None
    where: str | None
    message: str

    def __str__(self) -> str:
        place = (self.file or "") + (f" [{self.where}]" if self.where else "")
        return f"{place}: {self.message}" if place else self.message


def finding(error: Exception) -> Finding:
    """The :class:`Finding` an error names: its file and key (ConfigError), row (DataError)
    or line and field (RecordError, ModelicaError); else its message alone."""
    if isinstance(error, ConfigError):
        return Finding(error.file, error.key, error.detail)
    if isinstance(error, DataError):
        return Finding(error.file, f"row {error.row}" if error.row is not None else None, error.detail)
    if isinstance(error, RecordError):
        what = f"field {error.field} = {error.value!r}: " if error.field is not None else ""
        tail = f" (allowed: {error.allowed})" if error.allowed else ""
        return Finding(error.file, f"line {error.line}" if error.line else None, what + error.detail + tail)
    if isinstance(error, ModelicaError):
        return Finding(error.file, f"line {error.line}" if error.line else None, error.detail)
    return Finding(None, None, str(error))


class CheckFailed(RapidCosimError):
    """What a run would stop on, found before it starts: every problem at once."""

    def __init__(self, what: str, findings: list[Finding]):
        self.what, self.findings = what, list(findings)
        listed = "\n".join(f"  {f}" for f in self.findings)
        super().__init__(f"{what}: {len(self.findings)} problem(s), nothing was run:\n{listed}")

    def one_line(self) -> str:
        """The problems on one line (a table's row)."""
        return f"{len(self.findings)} problem(s), nothing was run: " + "; ".join(map(str, self.findings))
