"""``pipeline.libmsg``: the command's capture of what the image/video libraries write to fd 2."""

import os
import signal

import pytest

from pipeline import libmsg
from pipeline._signals import Interrupts


def test_a_signal_while_the_capture_starts_finds_it_whole(monkeypatch):
    """SIGTERM arriving in the middle of ``start`` (right after the pipe is made) is raised when
    ``start`` returns: the reader thread is running and ``stop`` puts fd 2 back. Raised at once,
    it left fd 2 on a pipe nobody reads, or a thread that could not be joined."""
    real_pipe = os.pipe

    def pipe():
        os.kill(os.getpid(), signal.SIGTERM)
        return real_pipe()

    interrupts = Interrupts()
    interrupts.install()
    monkeypatch.setattr(libmsg.os, "pipe", pipe)
    before = os.fstat(2)
    m = libmsg.LibraryMessages()
    try:
        with pytest.raises(KeyboardInterrupt):
            m.start()
        assert m._thread is not None and m._thread.is_alive()
    finally:
        monkeypatch.undo()
        m.stop()
        interrupts.restore()
    after = os.fstat(2)
    assert (after.st_dev, after.st_ino) == (before.st_dev, before.st_ino)  # fd 2 is back
    assert interrupts.count == 1
