"""Exceptions that the CLI turns into one line on stderr and exit status 1."""

from __future__ import annotations


class InputError(Exception):
    """Bad input from the user: a missing folder, an unreadable frame, a malformed file.

    The message is a single line that says what is wrong and where (file, line, frame).
    """


class ConfigError(InputError):
    """A configuration value or file that cannot be used."""


class OutputError(InputError):
    """A run's outputs cannot be written (a full disk, a read-only or missing folder); names the
    file."""


def describe_os_error(exc: OSError, what: str = "") -> str:
    """One line for an OS error: ``what`` (or the file) and the system's reason."""
    name = exc.filename if exc.filename is not None else ""
    reason = exc.strerror or type(exc).__name__
    where = what or (f"{name}" if name else "")
    return f"{where}: {reason}" if where else reason
