"""Text files written in whole rows, durable at checkpoints.

A :class:`RowFile` buffers its rows and writes them at each checkpoint with one ``write``;
a write that fails (a full disk) is undone by truncating the file back to where it was, so
the file always ends with a complete row and holds exactly the frames of the last
checkpoint that succeeded. Checkpoints are the moments ``summary.json`` is rewritten, so
after any fault, a kill included, ``summary.json`` says how many frames the files hold.
"""

from __future__ import annotations

import errno
import os
from pathlib import Path

from pipeline.errors import OutputError, describe_os_error


class RowFile:
    """One text file of rows (``\\n``-terminated lines), written at checkpoints (unbuffered, so a
    failed write leaves nothing pending that a later flush could half-write)."""

    def __init__(self, path: Path, header: str | None = None):
        self.path = Path(path)
        try:
            self._fd: int | None = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        except OSError as exc:
            raise OutputError(f"cannot write {describe_os_error(exc, str(self.path))}") from None
        self._pos = 0
        self._checkpoint_pos = 0  # where the file ended before the last checkpoint
        self._rows: list[str] = []
        if header is not None:
            self.add(header)
            self.checkpoint()

    def add(self, row: str) -> None:
        """Queue one row (without its line end) for the next checkpoint."""
        self._rows.append(row + "\n")

    def write(self, text: str) -> None:
        """Queue text that ends with a line end (``csv.writer(rowfile)`` writes its rows this
        way)."""
        self._rows.append(text)

    def checkpoint(self) -> None:
        """Write the queued rows; on failure the file is truncated back and :class:`OutputError` is
        raised."""
        if not self._rows or self._fd is None:
            return
        data = "".join(self._rows).encode("utf-8")
        self._rows = []
        self._checkpoint_pos = self._pos
        view = memoryview(data)
        done = 0
        try:
            while done < len(data):
                n = os.write(self._fd, view[done:])
                # a file system that reports a full disk as a write of nothing: no retry helps
                if n == 0:
                    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
                done += n
        except OSError as exc:
            try:
                os.ftruncate(self._fd, self._pos)
                os.lseek(self._fd, self._pos, os.SEEK_SET)
            except OSError:
                pass
            raise OutputError(f"cannot write {describe_os_error(exc, str(self.path))}") from None
        self._pos += len(data)

    def rollback(self) -> None:
        """Undo the last checkpoint (the run loop's checkpoint failed after this file's part of it
        succeeded)."""
        if self._fd is None:
            return
        try:
            os.ftruncate(self._fd, self._checkpoint_pos)
            os.lseek(self._fd, self._checkpoint_pos, os.SEEK_SET)
            self._pos = self._checkpoint_pos
        except OSError:
            pass

    def close(self) -> None:
        """Write what is queued and close the file (a failure to write still closes it, then
        raises)."""
        if self._fd is None:
            return
        try:
            self.checkpoint()
        finally:
            fd, self._fd = self._fd, None
            try:
                os.close(fd)
            except OSError:
                pass
