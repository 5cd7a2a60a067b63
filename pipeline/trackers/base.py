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

import dataclasses
import functools
from collections.abc import Callable, Sequence
from typing import Generic, Protocol, TypeVar

from pipeline.config import PipelineConfig
from pipeline.io.sequence import FramePair
from pipeline.stages.detection import DetectionConfig
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


class BackgroundEngine(FunctionalEngine[S]):
    """A functional engine whose detector uses the background of the whole sequence.

    Its ``init`` takes a ``background`` keyword and its state has a ``background`` field; once
    :meth:`attach` has been given the sequence (``detection.background_init = "sequence"``), every
    frame's background (:class:`pipeline.io.background.SequenceBackground`) is put there before the
    frame is stepped. Not attached, the state's background is whatever ``init`` and ``step`` leave.
    ``channel`` picks the detector's channel from the sequence's channels. With ``lazy``, what is
    put there is a function of no arguments returning the background, so that a tracker that seldom
    runs its detector (the dual tracker's whole-frame search) reads the sequence's samples only if
    it does. ``detection`` gives the detection settings the engine's detector runs with (default:
    the configuration's ``detection`` section), which decide what the background estimates.
    """

    def __init__(
        self,
        name: str,
        init: Callable[..., tuple[S, FrameResult]],
        step: Callable[[S, FramePair, PipelineConfig], tuple[S, FrameResult]],
        cfg: PipelineConfig,
        channel: Callable[[tuple[str, ...], PipelineConfig], str],
        lazy: bool = False,
        detection: Callable[[PipelineConfig], DetectionConfig] | None = None,
    ):
        super().__init__(name, init, step, cfg)
        self._channel = channel
        self._detection = detection
        self._lazy = lazy
        self._source = None

    def attach(self, seq) -> None:
        from pipeline.io.background import sequence_background

        dcfg = self._detection(self.cfg) if self._detection is not None else self.cfg.detection
        self._source = sequence_background(seq, self._channel(tuple(seq.channels), self.cfg), dcfg)

    def _background(self, index: int):
        if self._source is None:
            return None
        return functools.partial(self._source.at, index) if self._lazy else self._source.at(index)

    def start(self, frames: FramePair, targets: Sequence[InitTarget]) -> FrameResult:
        self.state, result = self._init(
            frames, targets, self.cfg, background=self._background(frames.index)
        )
        return result

    def step(self, frames: FramePair) -> FrameResult:
        if self.state is not None and self._source is not None:
            self.state = dataclasses.replace(self.state, background=self._background(frames.index))
        return super().step(frames)


def detector_channel(channels: tuple[str, ...], cfg: PipelineConfig) -> str:
    """The channel the detector runs on: ``detection.channel`` if present, else the other."""
    pref = cfg.detection.channel
    return pref if pref in channels else ("visible" if pref == "infrared" else "infrared")


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
