"""Exceptions that the CLI turns into one line on stderr and exit status 1."""

from __future__ import annotations


class InputError(Exception):
    """Bad input from the user: a missing folder, an unreadable frame, a malformed file.

    The message is a single line that says what is wrong and where (file, line, frame).
    """


class ConfigError(InputError):
    """A configuration value or file that cannot be used."""
