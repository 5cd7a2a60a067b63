"""The run loop's writer: frames reach the sinks in order, whichever thread writes them."""

from __future__ import annotations

import random
import threading
import time

import pytest

from pipeline.runloop import _Writer


class _Recorder:
    """A sink that records which frame it was given, on which thread, and its checkpoints."""

    def __init__(self, fail_at: int | None = None, slow_s: float = 0.0):
        self.frames: list[int] = []
        self.threads: set[str] = set()
        self.checkpoints: list[int] = []
        self.closed = False
        self.fail_at, self.slow_s = fail_at, slow_s

    def write(self, frames, item) -> None:
        if item == self.fail_at:
            raise OSError("disk full")
        time.sleep(self.slow_s)
        self.frames.append(item)
        self.threads.add(threading.current_thread().name)

    def checkpoint(self) -> None:
        self.checkpoints.append(len(self.frames))

    def close(self) -> None:
        self.closed = True


def test_frames_reach_the_sinks_in_order_when_the_writing_thread_switches():
    """``ahead`` flips at random: frames go to the writer thread or are written inline, and
    an inline frame waits for what the thread still holds."""
    rng = random.Random(3)
    sink = _Recorder(slow_s=0.0005)
    w = _Writer([sink], 10, lambda n: None, threaded=True, ahead=lambda: rng.random() < 0.5)
    for i in range(200):
        w.put(None, i)
    w.close()
    assert sink.frames == list(range(200))
    assert sink.threads == {"dualtrack-writer", threading.current_thread().name}
    assert sink.checkpoints == [*range(10, 201, 10), 200]  # every 10 frames, and at close
    assert sink.closed and w.written == 200 and w.error is None


@pytest.mark.parametrize("ahead", [True, False])
def test_the_thread_that_writes_is_the_one_the_reader_asks_for(ahead):
    sink = _Recorder()
    w = _Writer([sink], 50, lambda n: None, threaded=True, ahead=lambda: ahead)
    for i in range(20):
        w.put(None, i)
    w.close()
    main = threading.current_thread().name
    assert sink.threads == ({main} if ahead else {"dualtrack-writer"})
    assert sink.frames == list(range(20))


def test_a_sink_failure_on_the_writer_thread_stops_the_writes_and_is_raised():
    sink = _Recorder(fail_at=5)
    w = _Writer([sink], 4, lambda n: None, threaded=True, ahead=lambda: False)
    with pytest.raises(OSError, match="disk full"):
        for i in range(100):
            w.put(None, i)
            time.sleep(0.001)
    w.close()
    assert sink.frames == [0, 1, 2, 3, 4] and w.written == 4  # the last checkpoint stands
    assert sink.closed
