"""``rapid-cosim``: the parser (:mod:`.parser`) hands a command (:mod:`.commands`) its
arguments; here, what every command shares: a user's error said in one line with the
key's reference, warnings said once, SIGTERM ending a run as Ctrl-C does (resumable)."""

from __future__ import annotations

import sys

from ..errors import RapidCosimError, RunInterrupted
from .parser import build_parser


class _Warnings:
    """Each warning said once, as a sentence (not the source line that raised it); how
    often each recurred is said when the command ends."""

    def __init__(self):
        self.seen: dict[tuple[str, type], int] = {}

    def show(self, message, category, filename, lineno, file=None, line=None) -> None:
        key = (str(message), category)
        self.seen[key] = self.seen.get(key, 0) + 1
        if self.seen[key] == 1:
            print(f"warning: {message}", file=sys.stderr)

    def recurred(self) -> None:
        again = [(text, n) for (text, _), n in self.seen.items() if n > 1]
        for text, n in again:
            print(f"warning said {n} times: {text[:100]}{'...' if len(text) > 100 else ''}", file=sys.stderr)


def _reference(error: RapidCosimError) -> str:
    """What the reference says of the key an error names (docs/config.md), if it does."""
    from ..errors import ConfigError
    from ..experiment.schema import explain

    words = explain(error.key) if isinstance(error, ConfigError) and error.key else None
    return f"\n  (the key: {words})" if words else ""


def _terminate(signum, frame):
    raise KeyboardInterrupt  # SIGTERM ends a run as Ctrl-C does: archive closed, resumable


def main(argv: list[str] | None = None) -> int:
    import signal
    import threading
    import warnings

    args = build_parser().parse_args(argv)
    main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, _terminate) if main_thread else None
    said = _Warnings()
    with warnings.catch_warnings():  # restores the filters and showwarning on exit
        warnings.filterwarnings("always", category=UserWarning)  # counted and said once by _Warnings
        warnings.showwarning = said.show
        try:
            return args.func(args)
        except RunInterrupted as e:
            print(f"rapid-cosim {args.command}: {e}", file=sys.stderr)
            return 130
        except RapidCosimError as e:
            print(f"rapid-cosim {args.command}: error: {e}{_reference(e)}", file=sys.stderr)
            return 2
        except KeyboardInterrupt:
            print("interrupted", file=sys.stderr)
            return 130
        finally:
            said.recurred()
            if main_thread:
                signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":
    sys.exit(main())
