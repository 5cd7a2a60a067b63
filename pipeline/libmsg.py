"""What the image and video libraries write to standard error, kept off the terminal.

libpng, libjpeg, FFmpeg and OpenCV's own log write their complaints straight to file
descriptor 2, before (or instead of) the error the tool reports: a truncated PNG prints
``libpng error: PNG input buffer is incomplete`` and then the tool's line. In the
``dualtrack`` command (:func:`pipeline._entry.entry`) :class:`LibraryMessages` points file
descriptor 2 at a pipe: Python's own writes (``sys.stderr``) go to the real standard error,
a thread reads the pipe, keeps the lines that are a library's (:data:`LIBRARY_LINE`) and
passes every other line through. The tool's messages then say what the library said, in
their one line: :func:`library_says` (``... is not a decodable image (libpng error: PNG input
buffer is incomplete)``); what was said of frames that still decoded is summed up in one
warning at the end (:meth:`LibraryMessages.unreported`).

Outside the command (the Python API, the test suite) nothing is redirected and
:func:`library_says` returns ``""``.
"""

from __future__ import annotations

import io
import os
import re
import sys
import threading

from pipeline._signals import held

__all__ = ["LIBRARY_LINE", "LibraryMessages", "library_says"]

LIBRARY_LINE = re.compile(
    r"^(libpng (error|warning)|libtiff|TIFF\w*:|Corrupt JPEG data|Premature end of JPEG"
    r"|Invalid JPEG|Not a JPEG file|Bogus |Unsupported marker|Wrong JPEG"
    r"|\[[\w,]+ @ 0x[0-9a-f]+\]|\[ ?(ERROR|WARN|INFO|DEBUG)[:\]])"
)
"""A line some image or video library wrote: libpng, libtiff, libjpeg, FFmpeg
(``[mov,mp4,... @ 0x...]``), OpenCV's log (``[ERROR:0@0.03] ...``)."""

_SYNC = "\x00dualtrack-sync "
_FFMPEG = re.compile(r"^\[[\w,]+ @ 0x[0-9a-f]+\] *")
_OPENCV = re.compile(r"^\[ ?(ERROR|WARN|INFO|DEBUG)[^\]]*\] *(global )?(\S+:\d+ \w+ )?")


def plain(line: str) -> str:
    """A library line without its machine prefix: FFmpeg's ``[mov,mp4,... @ 0x55...]`` becomes
    ``FFmpeg:``, OpenCV's ``[ERROR:0@0.04] global grfmt_png.cpp:296 readHeader`` ``OpenCV:``."""
    if _FFMPEG.match(line):
        return "FFmpeg: " + _FFMPEG.sub("", line)
    if _OPENCV.match(line):
        return "OpenCV: " + _OPENCV.sub("", line)
    return line


class LibraryMessages:
    """File descriptor 2 through a pipe whose library lines are kept (module doc).

    :meth:`start` and :meth:`stop` bracket a command; in between :meth:`take` returns the
    library lines written so far and not yet taken.
    """

    def __init__(self) -> None:
        self._lines: list[str] = []
        self._cond = threading.Condition()
        self._seen_sync = 0
        self._next_sync = 0
        self._thread: threading.Thread | None = None
        self._real = -1
        self._stderr: object = None

    def start(self) -> None:
        """Redirect file descriptor 2 (no-op where it cannot be duplicated).

        The command's SIGINT and SIGTERM are held back while it runs and raised when it returns
        (:class:`pipeline._signals.held`), so an interruption finds the redirection whole, its
        reader thread started: never a descriptor 2 that nothing reads, or a thread that cannot
        be joined."""
        with held():
            self._start()

    def _start(self) -> None:
        try:
            sys.stderr.flush()
            self._real = os.dup(2)
            r, w = os.pipe()
            os.dup2(w, 2)
            os.close(w)
        except OSError:
            return
        self._stderr = sys.stderr
        sys.stderr = io.TextIOWrapper(
            io.FileIO(self._real, "w", closefd=False),
            encoding=getattr(sys.stderr, "encoding", None) or "utf-8",
            errors="backslashreplace",
            line_buffering=True,
        )
        self._thread = threading.Thread(target=self._read, args=(r,), daemon=True)
        self._thread.start()

    def _read(self, fd: int) -> None:
        with open(fd, "rb", buffering=0) as pipe:
            pending = b""
            while chunk := pipe.read(65536):
                pending += chunk
                *lines, pending = pending.split(b"\n")
                for raw in lines:
                    self._line(raw)
            if pending:
                self._line(pending)

    def _line(self, raw: bytes) -> None:
        text = raw.decode("utf-8", "backslashreplace").rstrip("\r")
        if text.startswith(_SYNC):
            with self._cond:
                self._seen_sync = int(text[len(_SYNC) :])
                self._cond.notify_all()
        elif LIBRARY_LINE.match(text):
            with self._cond:
                self._lines.append(plain(text))
        else:
            os.write(self._real, raw + b"\n")

    def take(self) -> list[str]:
        """The library lines written before this call and not taken before."""
        if self._thread is None:
            return []
        with self._cond:
            self._next_sync += 1
            n = self._next_sync
        os.write(2, f"{_SYNC}{n}\n".encode())
        with self._cond:
            self._cond.wait_for(lambda: self._seen_sync >= n, timeout=1.0)
            out, self._lines = self._lines, []
        return out

    def unreported(self) -> str | None:
        """One line summing up the library lines no error took (a JPEG that decoded with a
        warning), or None."""
        rest = self.take()
        if not rest:
            return None
        n = len(rest)
        return f"{n} message{'s' * (n > 1)} from the image/video libraries, the first: {rest[0]}"

    def stop(self) -> None:
        """Put file descriptor 2 back and wait (briefly) for the reader to finish."""
        if self._thread is None:
            return
        sys.stderr.flush()
        os.dup2(self._real, 2)  # closes the pipe's write end held at 2
        self._thread.join(timeout=2.0)
        sys.stderr = self._stderr  # type: ignore[assignment]
        os.close(self._real)
        self._thread = None


_active: LibraryMessages | None = None


def install(messages: LibraryMessages | None) -> None:
    """Make ``messages`` the one :func:`library_says` reads (None: none)."""
    global _active
    _active = messages


def library_says() -> str:
    """What the image/video libraries wrote since it was last asked, as ``" (...)"`` to end
    an error message with (the last two lines); ``""`` when they said nothing or outside the
    command."""
    if _active is None:
        return ""
    lines = _active.take()
    return f" ({'; '.join(lines[-2:])})" if lines else ""
