"""``<archive>.lock``: one writer per archive, across processes.

The lock file is created with O_EXCL and holds pid, host and process start time. A lock
whose process is gone from this host is taken over with a warning; a live one raises
:class:`ArchiveLocked`. Readers take no lock.
"""

from __future__ import annotations

import json
import os
import socket
import time
import warnings

from ..errors import ArchiveLocked

def _process_start(pid: int) -> str | None:
    """Start time of ``pid`` in clock ticks since boot (Linux), to detect pid reuse."""
    try:
        with open(f"/proc/{pid}/stat") as fh:
            fields = fh.read().rsplit(")", 1)[1].split()
    except OSError:
        return None
    if fields[0] in ("Z", "X"):  # a zombie has finished running
        return "dead"
    return fields[19]


def _alive(pid: int, start: str | None) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        pass  # another user's live process
    now = _process_start(pid)
    if now == "dead":
        return False
    return start is None or now is None or now == start


class Lock:
    """``<archive>.lock``: created with O_EXCL, removed on release."""

    GRACE = 30.0  # seconds an unreadable lock (holder died while writing it) is respected

    def __init__(self, archive: str):
        self.archive = archive
        self.path = archive + ".lock"
        pid = os.getpid()
        self.content = json.dumps(
            {"pid": pid, "host": socket.gethostname(), "start": _process_start(pid)}
        )
        self.held = False

    def acquire(self) -> None:
        for _ in range(3):
            try:
                fd = os.open(self.path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            except FileExistsError:
                self._clear_stale()
                continue
            with os.fdopen(fd, "w") as fh:
                fh.write(self.content)
                fh.flush()
                os.fsync(fh.fileno())
            self.held = True
            return
        raise ArchiveLocked(f"{self.archive}: could not take the lock {self.path}")

    def _clear_stale(self) -> None:
        """Remove the lock if its holder is gone, else raise :class:`ArchiveLocked`."""
        try:
            with open(self.path) as fh:
                text = fh.read()
            age = time.time() - os.stat(self.path).st_mtime
        except FileNotFoundError:
            return  # released meanwhile
        try:
            holder = json.loads(text)
            pid, host = int(holder["pid"]), str(holder["host"])
        except (ValueError, KeyError, TypeError):
            if age < self.GRACE:
                raise ArchiveLocked(
                    f"{self.archive} is being opened by another process (lock {self.path})"
                ) from None
            warnings.warn(f"{self.archive}: removing unreadable lock {self.path}", stacklevel=4)
        else:
            if host != socket.gethostname():
                raise ArchiveLocked(
                    f"{self.archive} is held by pid {pid} on host {host} (lock {self.path}); "
                    "if that run is gone, delete the lock file"
                )
            if _alive(pid, holder.get("start")):
                raise ArchiveLocked(
                    f"{self.archive} is held by a live run, pid {pid} on {host} (lock {self.path})"
                )
            warnings.warn(
                f"{self.archive}: taking over the stale lock of pid {pid}, no longer running",
                stacklevel=4,
            )
        # Two processes taking over the same stale lock in the same instant could both
        # succeed; resumes of one archive are not started that way.
        try:
            os.unlink(self.path)
        except FileNotFoundError:
            pass

    def release(self) -> None:
        if not self.held:
            return
        self.held = False
        try:
            with open(self.path) as fh:
                mine = fh.read() == self.content
            if mine:
                os.unlink(self.path)
        except FileNotFoundError:
            pass
