"""The tracker interface every engine implements.

An engine is started on the first frame pair with the initial targets and then stepped
once per frame pair; both return a :class:`~pipeline.types.FrameResult` with one
:class:`~pipeline.types.TargetResult` per target (box, status, diagnostics)::

    engine = make_tracker("dual", cfg)
    first = engine.start(frames_1, init_targets)
    for frames in rest:
        result = engine.step(frames)

An engine that looks at the whole sequence before its first frame (the detector's background
of a still camera) has an ``attach(seq)`` method too, which the runner calls before ``start``
(:func:`attach_sequence`).

Our own trackers are written as pure functions over frozen per-target state,
``init(frames, targets, cfg) -> state`` and ``step(state, frames, cfg) -> (state,
FrameResult)``; :class:`FunctionalEngine` holds the state between calls so the runner
sees the same interface as the OpenCV peers (whose state lives inside OpenCV objects).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Generic, Protocol, TypeVar

from pipeline.config import PipelineConfig
from pipeline.io.sequence import FramePair
from pipeline.types import FrameResult, InitTarget

S = TypeVar("S")


class Engine(Protocol):
    """What the runner drives: ``start`` on frame 1, then ``step`` on every later frame."""

    name: str

    def start(self, frames: FramePair, targets: Sequence[InitTarget]) -> FrameResult: ...

    def step(self, frames: FramePair) -> FrameResult: ...


class FunctionalEngine(Generic[S]):
    """Adapter from a pure ``init``/``step`` pair to the :class:`Engine` interface.

    ``state`` is public so tests and tools can inspect or replay it.
    """

    def __init__(
        self,
        name: str,
        init: Callable[[FramePair, Sequence[InitTarget], PipelineConfig], tuple[S, FrameResult]],
        step: Callable[[S, FramePair, PipelineConfig], tuple[S, FrameResult]],
        cfg: PipelineConfig,
    ):
        self.name = name
        self._init = init
        self._step = step
        self.cfg = cfg
        self.state: S | None = None

    def start(self, frames: FramePair, targets: Sequence[InitTarget]) -> FrameResult:
        self.state, result = self._init(frames, targets, self.cfg)
        return result

    def step(self, frames: FramePair) -> FrameResult:
        if self.state is None:
            raise RuntimeError(f"{self.name}: step() called before start()")
        self.state, result = self._step(self.state, frames, self.cfg)
        return result


def attach_sequence(engine: Engine, seq: object) -> None:
    """Give ``engine`` the sequence it will run on, if it has use for it (an ``attach`` method)."""
    attach = getattr(engine, "attach", None)
    if attach is not None:
        attach(seq)


def pick_channel(frames: FramePair, preferred: str = "visible") -> str:
    """The channel a one-channel engine works on: ``preferred`` if present, else the other."""
    if getattr(frames, preferred) is not None:
        return preferred
    return "infrared" if preferred == "visible" else "visible"
