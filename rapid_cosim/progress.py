"""Progress an engineer reads: a tqdm bar on a terminal, plain lines in a log.

A bar redrawn with carriage returns is right on a terminal and wrong in a file, where
every frame stays as a line of ``\\r``-joined text. :class:`Stage` draws a bar only where
its stream is a terminal; elsewhere it writes one line when the stage starts, one at
most every ``every`` seconds while it runs, and one when it ends. A stage without a known
length (an optimiser that stops when it converges) counts up instead of jumping from
part-way to the end."""

from __future__ import annotations

import sys
import time
from typing import TextIO


class Stage:
    """One stage's progress (module docstring); ``total`` None: counted, not bounded."""

    def __init__(self, desc: str, total: int | None = None, *, unit: str = "it", enabled: bool = True,
                 stream: TextIO | None = None, every: float = 10.0, quiet_start: bool = False):
        self.desc, self.total, self.unit, self.every = desc, total, unit, every
        self.stream = stream if stream is not None else sys.stderr
        self.n, self.note, self.started = 0, "", time.monotonic()
        self.enabled, self.bar, self._said = enabled, None, self.started
        if not enabled:
            return
        if _is_terminal(self.stream):
            from tqdm.auto import tqdm

            self.bar = tqdm(total=total, desc=desc, unit=unit, file=self.stream, dynamic_ncols=True)
        elif not quiet_start:  # quiet: the caller's own line has said it started
            self._line(f"started{f', {total} {unit}' if total else ''}")

    def update(self, n: int = 1, note: str = "") -> None:
        self.n += n
        if not self._noted(note):
            return
        if self.bar is not None:
            self.bar.update(n)
        elif time.monotonic() - self._said >= self.every:
            self._line(self._count())

    def close(self, note: str = "") -> None:
        if not self._noted(note):
            return
        if self.bar is not None:
            self.bar.close()
            self.bar = None
        else:
            self._line(f"done, {self._count()} in {time.monotonic() - self.started:.0f} s")
        self.enabled = False

    def _noted(self, note: str) -> bool:
        """Keep ``note`` (on the bar too); whether there is anything to show."""
        self.note = note or self.note
        if self.enabled and self.bar is not None and note:
            self.bar.set_postfix_str(note, refresh=False)
        return self.enabled

    def __enter__(self) -> "Stage":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _count(self) -> str:
        count = f"{self.n}{f' of {self.total}' if self.total else ''} {self.unit}"
        return f"{count}, {self.note}" if self.note else count

    def _line(self, words: str) -> None:
        self._said = time.monotonic()
        print(f"{self.desc}: {words}", file=self.stream, flush=True)


def _is_terminal(stream: TextIO) -> bool:
    try:
        return stream.isatty()
    except (AttributeError, ValueError):  # a closed or stream-like object
        return False


class StagedLog:
    """A ``log`` for a long job that reports in lines (``identify``): each unindented line
    ending in ``:`` opens a stage (``the explanation ...:``, ``the standard records:``),
    and each line that reports a fit (it names a ``BIC``) counts one fit done in it. On a
    terminal each stage is a counting bar with its elapsed time, the lines printed above
    it; in a log the lines pass as they are, with the stage's count and time at most
    every ``every`` seconds as its fits finish, and a line when it ends."""

    def __init__(self, *, enabled: bool = True, stream: TextIO | None = None, every: float = 30.0):
        self.enabled, self.every = enabled, every
        self.stream = stream if stream is not None else sys.stdout
        self.terminal = enabled and _is_terminal(self.stream)
        self.stage: Stage | None = None

    def __call__(self, line: str) -> None:
        if self.enabled and line.endswith(":") and not line.startswith(" "):
            self.close()
            self.stage = Stage(line.rstrip(":").strip(), None, unit="fit", stream=self.stream, every=self.every,
                               quiet_start=not self.terminal)
        if self.terminal and self.stage is not None and self.stage.bar is not None:
            self.stage.bar.write(line, file=self.stream)
        else:
            print(line, file=self.stream, flush=True)
        if self.stage is not None and "BIC" in line:
            self.stage.update(1, line.strip().split(":")[0])

    def close(self) -> None:
        if self.stage is not None:
            self.stage.close()
            self.stage = None
