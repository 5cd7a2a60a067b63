"""The ``dualtrack`` command's first instant: SIGINT and SIGTERM are taken before anything heavy
is imported, so a Ctrl-C at any moment our code runs ends in one ``interrupted`` line and exit
130. (A signal that arrives while the interpreter itself is still starting, before any of our
code, is the operating system's: the process ends by that signal, which a shell reports as
130 for SIGINT and 143 for SIGTERM.)

This module imports only the standard library and :mod:`pipeline._signals` before the command
runs."""

from __future__ import annotations

import os
import signal
import sys

from pipeline._signals import Interrupts

PROG = "dualtrack"


def _deaf() -> None:
    for s in (signal.SIGINT, signal.SIGTERM):
        signal.signal(s, signal.SIG_IGN)


def entry() -> None:
    """The ``dualtrack`` command (and ``python -m pipeline``): signals are taken first, then
    :func:`pipeline.cli.main` runs; the process exits with its status, deaf to further signals
    while the interpreter shuts down (a Ctrl-C then would cut the exit short)."""
    Interrupts().install()
    messages = None
    try:
        from pipeline import libmsg
        from pipeline.cli import main

        messages = libmsg.LibraryMessages()
        messages.start()
        libmsg.install(messages)
        code = main(hold=True)
    except KeyboardInterrupt:  # before main took the signals over
        print(f"{PROG}: interrupted", file=sys.stderr)
        code = 130
    _deaf()
    if messages is not None:
        said = messages.unreported()
        if said is not None:
            print(f"{PROG}: warning: {said}", file=sys.stderr)
        messages.stop()
    if code == 130:
        # An interruption that passed through some compiled modules' imports (SciPy's) marks the
        # interpreter, whose exit would then kill the process by SIGINT instead of returning
        # 130. Every output is closed by now (the sinks disconnect on the way out).
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(130)
    raise SystemExit(code)
