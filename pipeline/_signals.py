"""SIGINT and SIGTERM for the ``dualtrack`` command: the first stops it as Ctrl-C does, and the
count of those taken survives where Python drops the ``KeyboardInterrupt``. Imports only the
standard library's ``signal`` and ``threading``, so :mod:`pipeline._entry` can take the signals
before anything heavy is imported."""

from __future__ import annotations

import signal
import threading

_taken = 0  # signals taken by the installed Interrupts
_held = 0  # depth of the ``held`` blocks being run
_pending = False  # the first signal arrived inside a ``held`` block


def taken() -> int:
    """How many SIGINT/SIGTERM the command's :class:`Interrupts` have taken so far. Python drops
    an exception raised inside some callbacks (a weak-reference callback of an import lock), so
    the run loop and :func:`pipeline.cli.main` read this count instead of trusting that the
    ``KeyboardInterrupt`` arrived."""
    return _taken


class Interrupts:
    """SIGINT and SIGTERM stop a command as Ctrl-C does: the first raises ``KeyboardInterrupt``
    (the outputs are closed, ``interrupted`` is said, exit 130); later ones are counted while
    that happens. The run loop takes them over while it runs (``pipeline.runloop``) and gives
    them back."""

    def __init__(self) -> None:
        self.count = 0
        self.previous: dict[int, object] = {}

    def _handler(self, signum: int, frame: object) -> None:
        global _taken
        self.count += 1
        _taken = self.count
        if self.count == 1:
            if _held:
                global _pending
                _pending = True
                return
            raise KeyboardInterrupt

    def install(self) -> None:
        """Take SIGINT and SIGTERM (only in the main thread, where Python allows it)."""
        global _taken
        _taken = 0
        if threading.current_thread() is not threading.main_thread():
            return
        for s in (signal.SIGINT, signal.SIGTERM):
            self.previous[s] = signal.signal(s, self._handler)

    def restore(self) -> None:
        """Give the handlers found by :meth:`install` back."""
        global _taken
        _taken = 0
        for s, h in self.previous.items():
            signal.signal(s, h)  # type: ignore[arg-type]
        self.previous.clear()


class held:
    """A block that the command's first SIGINT/SIGTERM does not cut: taken inside it, the
    ``KeyboardInterrupt`` is raised as the block ends (unless the block raises already). For
    set-ups that must happen whole or not at all, such as redirecting a file descriptor and
    starting the thread that reads it. Blocks nest."""

    def __enter__(self) -> None:
        global _held
        _held += 1

    def __exit__(self, kind: object, value: object, tb: object) -> None:
        global _held, _pending
        _held -= 1
        if _held == 0 and _pending:
            _pending = False
            if kind is None:
                raise KeyboardInterrupt
