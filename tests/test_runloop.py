"""The run loop's writer: when checkpoints happen."""

from __future__ import annotations

import pytest

from pipeline import runloop


class _CountingSink:
    def __init__(self) -> None:
        self.written: list[int] = []
        self.checkpoints: list[int] = []

    def write(self, frames, item) -> None:
        self.written.append(item)

    def checkpoint(self) -> None:
        self.checkpoints.append(len(self.written))

    def close(self) -> None:
        pass


class _Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


@pytest.fixture
def clock(monkeypatch):
    c = _Clock()
    monkeypatch.setattr(runloop.time, "monotonic", c)
    return c


def _feed(writer, sink, clock, frames, seconds_per_frame):
    for i in range(1, frames + 1):
        clock.now += seconds_per_frame
        writer.put(None, i)
    return sink.checkpoints


def test_checkpoints_fall_on_multiples_once_the_floor_has_passed(clock):
    sink, summaries = _CountingSink(), []
    w = runloop._Writer([sink], 4, summaries.append, threaded=False, min_seconds=0.5)
    # 0.1 s a frame: 4 frames are 0.4 s, under the floor; 8 frames are 0.8 s
    assert _feed(w, sink, clock, 24, 0.1) == [8, 16, 24]
    assert summaries == [8, 16, 24] and w.written == 24


def test_a_fast_run_checkpoints_by_time_a_slow_one_by_frames(clock):
    fast, slow = _CountingSink(), _CountingSink()
    wf = runloop._Writer([fast], 4, lambda n: None, threaded=False, min_seconds=0.5)
    # 0.01 s a frame: the first multiple of 4 at least 0.5 s after the last checkpoint
    assert _feed(wf, fast, clock, 130, 0.01) == [52, 104]
    ws = runloop._Writer([slow], 4, lambda n: None, threaded=False, min_seconds=0.5)
    assert _feed(ws, slow, clock, 12, 1.0) == [4, 8, 12]


def test_no_floor_checkpoints_on_every_multiple(clock):
    sink = _CountingSink()
    w = runloop._Writer([sink], 3, lambda n: None, threaded=False, min_seconds=0.0)
    assert _feed(w, sink, clock, 10, 0.0) == [3, 6, 9]
